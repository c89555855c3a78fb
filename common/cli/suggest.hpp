// SPDX-License-Identifier: MIT
// "Did you mean": the closest known name to a mistyped one, by edit distance. Pure code, no
// CLI11 (pitmap-acqd parses its arguments by hand and uses it too).
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace pitmap::cli {

// Optimal string alignment distance: insertions, deletions, substitutions and transpositions
// of two neighbours cost 1 each ("lvie" -> "live" is 1, "georf" -> "georef" is 1). Bytes, case
// sensitive. O(|a| |b|) time, O(|b|) memory.
std::size_t EditDistance(std::string_view a, std::string_view b);

// The candidate closest to `typed`, when close enough to be a typo: a distance of at most
// max(1, length of the longer of the two / 3), or `typed` a prefix of exactly one candidate
// ("--vehic" -> "--vehicle"). Ties go to the first candidate. nullopt when nothing is close, or
// `typed` is itself a candidate. Leading dashes take part in the distance like any byte, so
// compare options with options ("--otu" vs "--out").
std::optional<std::string> ClosestMatch(std::string_view typed,
                                        const std::vector<std::string>& candidates);

// "; did you mean 'X'?" for a close candidate, else "".
std::string DidYouMean(std::string_view typed, const std::vector<std::string>& candidates);

}  // namespace pitmap::cli
