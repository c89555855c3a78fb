// SPDX-License-Identifier: MIT
#include "processor/io/water_level.hpp"

#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>

#include "common/gps_time.hpp"
#include "common/text.hpp"

namespace pitmap::proc::io {

namespace {

using text::ParseNumber;
using text::TrimBlanks;

std::optional<int> Digits(std::string_view s, std::size_t n) {
    if (s.size() != n) return std::nullopt;
    int v = 0;
    for (char c : s) {
        if (c < '0' || c > '9') return std::nullopt;
        v = v * 10 + (c - '0');
    }
    return v;
}

// "YYYY-MM-DDTHH:MM:SS[.fff]Z" -> GPS microseconds.
std::optional<std::int64_t> GpsFromIsoUtc(std::string_view s) {
    s = TrimBlanks(s);
    if (s.size() < 20 || s.size() > 40 || s.back() != 'Z') return std::nullopt;
    if (s[4] != '-' || s[7] != '-' || (s[10] != 'T' && s[10] != ' ') || s[13] != ':' ||
        s[16] != ':') {
        return std::nullopt;
    }
    const auto y = Digits(s.substr(0, 4), 4);
    const auto mo = Digits(s.substr(5, 2), 2);
    const auto d = Digits(s.substr(8, 2), 2);
    const auto h = Digits(s.substr(11, 2), 2);
    const auto mi = Digits(s.substr(14, 2), 2);
    const std::string_view sec_text = s.substr(17, s.size() - 18);
    if (sec_text.size() < 2 || sec_text[0] < '0' || sec_text[0] > '9') return std::nullopt;
    const auto sec = ParseNumber(sec_text);
    if (!y || !mo || !d || !h || !mi || !sec || *y < 1980 || *y > 2200 || *h > 23 || *mi > 59 ||
        *sec < 0 || *sec >= 61) {
        return std::nullopt;
    }
    UtcCalendar c;
    c.year = *y;
    c.month = *mo;
    c.day = *d;
    const auto midnight = UnixFromUtcCalendar(c);
    if (!midnight) return std::nullopt;
    const double tod = *h * 3600.0 + *mi * 60.0 + *sec;
    return GpsFromUnix(*midnight + static_cast<std::int64_t>(std::llround(tod * 1e6)));
}

std::string Quoted(std::string_view s) {
    std::string out = "'";
    for (char c : s.substr(0, 40)) out += (c >= 32 && c < 127) ? c : '?';
    if (s.size() > 40) out += "...";
    return out + "'";
}

}  // namespace

Expected<std::vector<WaterLevelSample>> ParseWaterLevelText(std::string_view text,
                                                            const std::string& name) {
    std::vector<WaterLevelSample> out;
    std::size_t pos = 0;
    int line_no = 0;
    bool header_allowed = true;
    while (pos < text.size()) {
        std::size_t end = text.find('\n', pos);
        if (end == std::string_view::npos) end = text.size();
        const std::string_view line = TrimBlanks(text.substr(pos, end - pos));
        pos = end + 1;
        ++line_no;
        const auto fail = [&](const std::string& what) {
            return Error{name + ":" + std::to_string(line_no) + ": " + what};
        };
        if (line.empty() || line.front() == '#') continue;
        const std::size_t sep = line.find_first_of(",;\t");
        if (sep == std::string_view::npos) {
            return fail("expected 'time,level', got " + Quoted(line));
        }
        const std::string_view f0 = TrimBlanks(line.substr(0, sep));
        std::string_view rest = line.substr(sep + 1);
        const std::size_t sep2 = rest.find_first_of(",;\t");
        const std::string_view f1 = TrimBlanks(rest.substr(0, sep2));
        if (header_allowed && !f0.empty() &&
            ((f0[0] >= 'a' && f0[0] <= 'z') || (f0[0] >= 'A' && f0[0] <= 'Z'))) {
            header_allowed = false;
            continue;
        }
        header_allowed = false;
        const auto t = GpsFromIsoUtc(f0);
        if (!t) return fail("time must be UTC as YYYY-MM-DDTHH:MM:SS[.fff]Z, got " + Quoted(f0));
        const auto level = ParseNumber(f1);
        if (!level) return fail("level must be a number (m), got " + Quoted(f1));
        if (std::abs(*level) > 10000) return fail("level " + Quoted(f1) + " is beyond 10 km");
        if (!out.empty() && *t <= out.back().utime_gps) {
            return fail("time " + Quoted(f0) + " does not follow the previous one");
        }
        if (out.size() >= kMaxWaterLevels) {
            return fail("more than " + std::to_string(kMaxWaterLevels) + " levels");
        }
        out.push_back({*t, *level});
    }
    if (out.empty()) return Error{name + ": no water level in the file"};
    return out;
}

Expected<std::vector<WaterLevelSample>> ReadWaterLevelFile(const std::string& path) {
    std::error_code ec;
    const auto size = std::filesystem::file_size(path, ec);
    if (ec) return Error{path + ": cannot read the water-level file (" + ec.message() + ")"};
    if (size > kMaxWaterLevelFileBytes)
        return Error{path + ": water-level file larger than 256 MiB"};
    std::ifstream in(path, std::ios::binary);
    if (!in) return Error{path + ": cannot open the water-level file"};
    std::ostringstream s;
    s << in.rdbuf();
    return ParseWaterLevelText(s.str(), path);
}

}  // namespace pitmap::proc::io
