// SPDX-License-Identifier: MIT
// Fields of the text files pitmap reads (sound-velocity casts, water-level series): blanks
// trimmed, whole fields parsed as finite numbers. One place, so the readers agree on what a
// number is.
#pragma once

#include <charconv>
#include <cmath>
#include <optional>
#include <string_view>
#include <system_error>

namespace pitmap::text {

// `s` without leading and trailing spaces, tabs and carriage returns.
inline std::string_view TrimBlanks(std::string_view s) {
    auto blank = [](char c) { return c == ' ' || c == '\t' || c == '\r'; };
    while (!s.empty() && blank(s.front())) s.remove_prefix(1);
    while (!s.empty() && blank(s.back())) s.remove_suffix(1);
    return s;
}

// A whole field as a finite double: blanks around it trimmed, a leading "+" accepted, nothing
// left over; NaN, infinities and out-of-range values are not numbers.
inline std::optional<double> ParseNumber(std::string_view s) {
    s = TrimBlanks(s);
    if (!s.empty() && s.front() == '+') s.remove_prefix(1);
    if (s.empty()) return std::nullopt;
    double v = 0;
    const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
    if (ec != std::errc() || ptr != s.data() + s.size() || !std::isfinite(v)) return std::nullopt;
    return v;
}

}  // namespace pitmap::text
