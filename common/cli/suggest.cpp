// SPDX-License-Identifier: MIT
#include "common/cli/suggest.hpp"

#include <algorithm>
#include <limits>

namespace pitmap::cli {

std::size_t EditDistance(std::string_view a, std::string_view b) {
    // Three rows of the dynamic programme: d(i, j) = min(d(i-1, j) + 1, d(i, j-1) + 1,
    // d(i-1, j-1) + [a_i != b_j], d(i-2, j-2) + 1 when a_i a_(i-1) = b_(j-1) b_j swapped).
    const std::size_t n = b.size();
    std::vector<std::size_t> before(n + 1), prev(n + 1), cur(n + 1);
    for (std::size_t j = 0; j <= n; ++j) prev[j] = j;
    for (std::size_t i = 1; i <= a.size(); ++i) {
        cur[0] = i;
        for (std::size_t j = 1; j <= n; ++j) {
            const std::size_t cost = a[i - 1] == b[j - 1] ? 0 : 1;
            cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + cost});
            if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1]) {
                cur[j] = std::min(cur[j], before[j - 2] + 1);
            }
        }
        std::swap(before, prev);
        std::swap(prev, cur);
    }
    return prev[n];
}

std::optional<std::string> ClosestMatch(std::string_view typed,
                                        const std::vector<std::string>& candidates) {
    if (typed.empty()) return std::nullopt;
    std::optional<std::string> best;
    std::size_t best_distance = std::numeric_limits<std::size_t>::max();
    std::vector<const std::string*> prefixed;
    for (const std::string& c : candidates) {
        if (c == typed) return std::nullopt;
        const std::size_t d = EditDistance(typed, c);
        const std::size_t limit = std::max<std::size_t>(1, std::max(c.size(), typed.size()) / 3);
        if (d <= limit && d < best_distance) {
            best = c;
            best_distance = d;
        }
        if (c.size() > typed.size() && c.compare(0, typed.size(), typed) == 0) {
            prefixed.push_back(&c);
        }
    }
    if (best) return best;
    // A prefix counts only past the dashes of an option ("--" prefixes every long option).
    const bool meaningful = typed.find_first_not_of('-') != std::string_view::npos;
    if (prefixed.size() == 1 && meaningful) return *prefixed.front();
    return std::nullopt;
}

std::string DidYouMean(std::string_view typed, const std::vector<std::string>& candidates) {
    const auto m = ClosestMatch(typed, candidates);
    return m ? "; did you mean '" + *m + "'?" : std::string();
}

}  // namespace pitmap::cli
