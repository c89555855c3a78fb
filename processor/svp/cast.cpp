// SPDX-License-Identifier: MIT
#include "processor/svp/cast.hpp"

#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <optional>

#include "common/gps_time.hpp"
#include "common/text.hpp"
#include "processor/svp/probe_casts.hpp"

namespace pitmap::proc::svp {

namespace {

using text::ParseNumber;
using text::TrimBlanks;

std::vector<std::string_view> SplitWhitespace(std::string_view s) {
    std::vector<std::string_view> out;
    std::size_t i = 0;
    while (i < s.size()) {
        while (i < s.size() && (s[i] == ' ' || s[i] == '\t' || s[i] == '\r')) ++i;
        std::size_t j = i;
        while (j < s.size() && s[j] != ' ' && s[j] != '\t' && s[j] != '\r') ++j;
        if (j > i) out.push_back(s.substr(i, j - i));
        i = j;
    }
    return out;
}

std::vector<std::string_view> SplitAny(std::string_view s, std::string_view seps) {
    std::vector<std::string_view> out;
    std::size_t start = 0;
    for (std::size_t i = 0; i <= s.size(); ++i) {
        if (i == s.size() || seps.find(s[i]) != std::string_view::npos) {
            out.push_back(TrimBlanks(s.substr(start, i - start)));
            start = i + 1;
        }
    }
    return out;
}

std::optional<int> Integer(std::string_view s, std::size_t digits_min, std::size_t digits_max) {
    if (s.size() < digits_min || s.size() > digits_max) return std::nullopt;
    int v = 0;
    for (char c : s) {
        if (c < '0' || c > '9') return std::nullopt;
        v = v * 10 + (c - '0');
    }
    return v;
}

std::string Quoted(std::string_view s) {
    std::string out = "'";
    for (char c : s.substr(0, 40)) out += (c >= 32 && c < 127) ? c : '?';
    if (s.size() > 40) out += "...";
    return out + "'";
}

// "HH:MM" or "HH:MM:SS[.fff]" -> seconds of the day.
std::optional<double> TimeOfDay(std::string_view s) {
    const auto parts = SplitAny(s, ":");
    if (parts.size() < 2 || parts.size() > 3) return std::nullopt;
    const auto h = Integer(parts[0], 1, 2);
    const auto m = Integer(parts[1], 1, 2);
    double sec = 0;
    if (parts.size() == 3) {
        const auto v = ParseNumber(parts[2]);
        if (!v || *v < 0 || *v >= 61) return std::nullopt;
        sec = *v;
    }
    if (!h || !m || *h > 23 || *m > 59) return std::nullopt;
    return *h * 3600.0 + *m * 60.0 + sec;
}

// Unix microseconds of a UTC calendar day plus seconds of the day.
std::optional<std::int64_t> UnixAt(int year, int month, int day, double seconds_of_day) {
    UtcCalendar c;
    c.year = year;
    c.month = month;
    c.day = day;
    const auto midnight = UnixFromUtcCalendar(c);
    if (!midnight) return std::nullopt;
    return *midnight + static_cast<std::int64_t>(std::llround(seconds_of_day * 1e6));
}

// "YYYY-DDD" and a time of day (CARIS section heading) -> GPS microseconds.
std::optional<std::int64_t> GpsFromYearDay(std::string_view date, std::string_view time) {
    const auto parts = SplitAny(date, "-/");
    if (parts.size() != 2) return std::nullopt;
    const auto year = Integer(parts[0], 4, 4);
    const auto doy = Integer(parts[1], 1, 3);
    const auto tod = TimeOfDay(time);
    if (!year || !doy || !tod || *year < 1980 || *doy < 1 || *doy > 366) return std::nullopt;
    const auto jan1 = UnixAt(*year, 1, 1, 0.0);
    if (!jan1) return std::nullopt;
    const std::int64_t day_start = *jan1 + static_cast<std::int64_t>(*doy - 1) * 86400000000LL;
    if (UtcCalendarFromUnix(day_start).year != *year) return std::nullopt;  // day 366, no leap
    return GpsFromUnix(day_start + static_cast<std::int64_t>(std::llround(*tod * 1e6)));
}

// ISO 8601 "YYYY-MM-DDTHH:MM:SS[.fff]Z" (or a space for T) -> GPS microseconds.
std::optional<std::int64_t> GpsFromIso(std::string_view s) {
    s = TrimBlanks(s);
    if (s.size() < 17 || s.back() != 'Z') return std::nullopt;
    s.remove_suffix(1);
    const std::size_t t = s.find_first_of("T ");
    if (t == std::string_view::npos) return std::nullopt;
    const auto ymd = SplitAny(s.substr(0, t), "-");
    if (ymd.size() != 3) return std::nullopt;
    const auto y = Integer(ymd[0], 4, 4);
    const auto mo = Integer(ymd[1], 1, 2);
    const auto d = Integer(ymd[2], 1, 2);
    const auto tod = TimeOfDay(s.substr(t + 1));
    if (!y || !mo || !d || !tod || *y < 1980) return std::nullopt;
    const auto unix = UnixAt(*y, *mo, *d, *tod);
    if (!unix) return std::nullopt;
    return GpsFromUnix(*unix);
}

// "DD:MM:SS.ss" / "-DDD:MM:SS" / "DD:MM.mmm" or decimal degrees.
std::optional<double> Angle(std::string_view s, double limit) {
    s = TrimBlanks(s);
    double sign = 1;
    if (!s.empty() && (s.front() == '-' || s.front() == '+')) {
        sign = s.front() == '-' ? -1 : 1;
        s.remove_prefix(1);
    }
    if (s.empty() || s.front() == '-' || s.front() == '+') return std::nullopt;
    double v = 0;
    if (s.find(':') == std::string_view::npos) {
        const auto d = ParseNumber(s);
        if (!d) return std::nullopt;
        v = *d;
    } else {
        const auto parts = SplitAny(s, ":");
        if (parts.size() < 2 || parts.size() > 3) return std::nullopt;
        const auto d = Integer(parts[0], 1, 3);
        const auto m = ParseNumber(parts[1]);
        const auto sec = parts.size() == 3 ? ParseNumber(parts[2]) : std::optional<double>(0.0);
        if (!d || !m || !sec || *m < 0 || *m >= 60 || *sec < 0 || *sec >= 60) return std::nullopt;
        v = *d + *m / 60.0 + *sec / 3600.0;
    }
    if (v > limit) return std::nullopt;
    return sign * v;
}

class Parser {
public:
    Parser(std::string_view text, const std::string& name) : text_(text), name_(name) {}

    std::optional<std::string_view> NextLine() {
        if (pos_ >= text_.size()) return std::nullopt;
        std::size_t end = text_.find('\n', pos_);
        if (end == std::string_view::npos) end = text_.size();
        const std::string_view line = text_.substr(pos_, end - pos_);
        pos_ = end + 1;
        ++line_;
        return line;
    }
    int line() const { return line_; }
    Error Fail(const std::string& what) const {
        return Error{name_ + ":" + std::to_string(line_) + ": " + what};
    }

private:
    std::string_view text_;
    const std::string& name_;
    std::size_t pos_ = 0;
    int line_ = 0;
};

// Adds a point to a cast, or says what is wrong with it.
std::optional<std::string> AddPoint(SoundSpeedCast& c,
                                    std::string_view depth_text,
                                    std::string_view speed_text) {
    const auto d = ParseNumber(depth_text);
    const auto v = ParseNumber(speed_text);
    if (!d) return "depth " + Quoted(depth_text) + " is not a number";
    if (!v) return "sound speed " + Quoted(speed_text) + " is not a number";
    if (*d < -1.0 || *d > 12000.0) {
        return "depth " + std::to_string(*d) + " m is outside [-1, 12000] m";
    }
    if (*v < kMinSpeedMps || *v > kMaxSpeedMps) {
        char buf[96];
        std::snprintf(buf,
                      sizeof(buf),
                      "sound speed %.3f m/s is outside [%.0f, %.0f] m/s",
                      *v,
                      kMinSpeedMps,
                      kMaxSpeedMps);
        return std::string(buf);
    }
    if (!c.depth_m.empty() && !(*d > c.depth_m.back())) {
        char buf[128];
        std::snprintf(buf,
                      sizeof(buf),
                      "depth %.3f m is not below the previous depth %.3f m (a cast must be one "
                      "monotonic profile)",
                      *d,
                      c.depth_m.back());
        return std::string(buf);
    }
    if (c.depth_m.size() >= kMaxCastPoints) {
        return "more than " + std::to_string(kMaxCastPoints) + " points in one cast";
    }
    c.depth_m.push_back(*d);
    c.speed_mps.push_back(*v);
    return std::nullopt;
}

Expected<std::vector<SoundSpeedCast>> ParseCaris(std::string_view text, const std::string& name) {
    Parser p(text, name);
    std::vector<SoundSpeedCast> casts;
    auto first = p.NextLine();
    if (!first || TrimBlanks(*first).rfind("[SVP_VERSION_", 0) != 0) {
        return p.Fail("not a CARIS .svp file: the first line must be [SVP_VERSION_2]");
    }
    const std::string_view version = TrimBlanks(*first);
    if (version != "[SVP_VERSION_1]" && version != "[SVP_VERSION_2]") {
        return p.Fail("unsupported CARIS version " + Quoted(version) +
                      " (known: [SVP_VERSION_1], [SVP_VERSION_2])");
    }
    if (!p.NextLine()) return p.Fail("no file name line after the version line");
    int section_line = 0;
    auto finish = [&]() -> std::optional<Error> {
        if (!casts.empty() && casts.back().depth_m.empty()) {
            return Error{name + ":" + std::to_string(section_line) + ": section without data"};
        }
        return std::nullopt;
    };
    while (auto line = p.NextLine()) {
        const std::string_view l = TrimBlanks(*line);
        if (l.empty()) continue;
        const auto f = SplitWhitespace(l);
        if (f.front() == "Section" || f.front() == "section") {
            if (auto e = finish()) return *e;
            if (f.size() < 5) {
                return p.Fail("section heading needs 'Section YYYY-DDD HH:MM:SS LAT LON', got " +
                              Quoted(l));
            }
            if (casts.size() >= kMaxCasts) {
                return p.Fail("more than " + std::to_string(kMaxCasts) + " casts");
            }
            SoundSpeedCast c;
            const auto t = GpsFromYearDay(f[1], f[2]);
            if (!t) {
                return p.Fail("section time " +
                              Quoted(std::string(f[1]) + " " + std::string(f[2])) +
                              " is not YYYY-DDD HH:MM:SS (UTC, day of year 1-366)");
            }
            const auto lat = Angle(f[3], 90.0);
            const auto lon = Angle(f[4], 180.0);
            if (!lat) return p.Fail("latitude " + Quoted(f[3]) + " is not DD:MM:SS or degrees");
            if (!lon) return p.Fail("longitude " + Quoted(f[4]) + " is not DDD:MM:SS or degrees");
            c.utime_gps = *t;
            // 0 0 is what writers put when the position is unknown.
            if (*lat != 0.0 || *lon != 0.0) {
                c.latitude_deg = *lat;
                c.longitude_deg = *lon;
            }
            c.name = name + " section " + std::to_string(casts.size() + 1);
            casts.push_back(std::move(c));
            section_line = p.line();
            continue;
        }
        if (casts.empty()) {
            return p.Fail("data before the first 'Section' heading: " + Quoted(l));
        }
        if (f.size() < 2) return p.Fail("expected 'depth speed', got " + Quoted(l));
        if (auto e = AddPoint(casts.back(), f[0], f[1])) return p.Fail(*e);
    }
    if (auto e = finish()) return *e;
    if (casts.empty()) return p.Fail("no 'Section' in the file");
    return casts;
}

// CSV (csv = true) or two-column text.
Expected<std::vector<SoundSpeedCast>> ParseColumns(std::string_view text,
                                                   const std::string& name,
                                                   bool csv) {
    Parser p(text, name);
    SoundSpeedCast c;
    c.name = name;
    bool header_allowed = csv;
    while (auto line = p.NextLine()) {
        std::string_view l = TrimBlanks(*line);
        if (l.empty()) continue;
        if (l.front() == '#') {
            l = TrimBlanks(l.substr(1));
            if (l.rfind("time:", 0) == 0) {
                const auto t = GpsFromIso(l.substr(5));
                if (!t) {
                    return p.Fail("'# time:' needs UTC as YYYY-MM-DDTHH:MM:SSZ, got " +
                                  Quoted(TrimBlanks(l.substr(5))));
                }
                c.utime_gps = *t;
            } else if (l.rfind("position:", 0) == 0) {
                const auto f = SplitWhitespace(l.substr(9));
                const auto lat = f.size() == 2 ? Angle(f[0], 90.0) : std::nullopt;
                const auto lon = f.size() == 2 ? Angle(f[1], 180.0) : std::nullopt;
                if (!lat || !lon) {
                    return p.Fail("'# position:' needs 'LAT LON' in degrees, got " +
                                  Quoted(TrimBlanks(l.substr(9))));
                }
                c.latitude_deg = *lat;
                c.longitude_deg = *lon;
            }
            continue;
        }
        const auto f = csv ? SplitAny(l, ",;") : SplitWhitespace(l);
        if (header_allowed && !f.empty() && !ParseNumber(f[0])) {
            std::string first(f[0]);
            for (char& ch : first)
                ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
            if (first.rfind("depth", 0) != 0) {
                return p.Fail("header line: the first column must be the depth, got " +
                              Quoted(f[0]));
            }
            header_allowed = false;
            continue;
        }
        header_allowed = false;
        if (csv && f.size() < 2) return p.Fail("expected 'depth,speed', got " + Quoted(l));
        if (!csv && f.size() != 2) {
            return p.Fail("expected two columns 'depth speed', found " + std::to_string(f.size()) +
                          ": " + Quoted(l));
        }
        if (auto e = AddPoint(c, f[0], f[1])) return p.Fail(*e);
    }
    if (c.depth_m.empty()) return Error{name + ": no depth/speed data"};
    return std::vector<SoundSpeedCast>{std::move(c)};
}

}  // namespace

const char* ToString(CastFormat f) {
    switch (f) {
        case CastFormat::kAuto:
            return "auto";
        case CastFormat::kCaris:
            return "caris";
        case CastFormat::kCsv:
            return "csv";
        case CastFormat::kTwoColumn:
            return "two_column";
        case CastFormat::kAml:
            return "aml";
        case CastFormat::kCastAway:
            return "castaway";
        case CastFormat::kHypackVel:
            return "hypack_vel";
        case CastFormat::kKongsbergAsvp:
            return "kongsberg_asvp";
        case CastFormat::kSimradS12:
            return "simrad_s12";
        case CastFormat::kSeaBirdCnv:
            return "seabird_cnv";
        case CastFormat::kSimradS10:
            return "simrad_s10";
        case CastFormat::kValeportMidas:
            return "valeport_midas";
    }
    return "?";
}

std::string KnownCastFormats() {
    return "CARIS .svp ([SVP_VERSION_2]), CSV (depth,speed), two-column text (depth speed), "
           "AML .csv ([cast header]), CastAway .csv (% Device), HYPACK .vel (FTP NEW), "
           "Kongsberg .asvp (( SoundVelocity), MVP .s12 ($xxS12), Sea-Bird .cnv (* Sea-Bird, "
           "# nquan), Simrad .ssp ($xxS10), Valeport MIDAS .000 (Date / Time columns)";
}

Expected<std::vector<SoundSpeedCast>> ParseCastText(std::string_view text,
                                                    const std::string& name,
                                                    CastFormat format) {
    if (text.find('\0') != std::string_view::npos) {
        return Error{name + ": binary data (a NUL byte) in a sound-velocity text file"};
    }
    if (format == CastFormat::kAuto) format = SniffProbeFormat(text);
    if (format == CastFormat::kAuto) {
        format = CastFormat::kTwoColumn;
        std::size_t pos = 0;
        bool first = true;
        while (pos < text.size()) {
            std::size_t end = text.find('\n', pos);
            if (end == std::string_view::npos) end = text.size();
            const std::string_view l = TrimBlanks(text.substr(pos, end - pos));
            pos = end + 1;
            if (l.empty()) continue;
            if (first && l.rfind("[SVP_VERSION", 0) == 0) {
                format = CastFormat::kCaris;
                break;
            }
            first = false;
            if (l.front() == '#') continue;
            if (l.find_first_of(",;") != std::string_view::npos) {
                format = CastFormat::kCsv;
            } else if (!ParseNumber(SplitWhitespace(l).front())) {
                return Error{name + ": not a sound-velocity cast format pitmap reads (line " +
                             Quoted(l) + "); known: " + KnownCastFormats()};
            }
            break;
        }
    }
    switch (format) {
        case CastFormat::kCaris:
            return ParseCaris(text, name);
        case CastFormat::kCsv:
            return ParseColumns(text, name, true);
        case CastFormat::kTwoColumn:
            return ParseColumns(text, name, false);
        default: {
            auto cast = ParseProbeCast(text, name, format);
            if (!cast) return cast.error();
            return std::vector<SoundSpeedCast>{std::move(*cast)};
        }
    }
}

std::vector<std::string> ValidateCast(const SoundSpeedCast& c) {
    std::vector<std::string> p;
    const std::string n = c.name.empty() ? "cast" : c.name;
    if (c.depth_m.empty()) p.push_back(n + ": no points");
    if (c.depth_m.size() != c.speed_mps.size()) p.push_back(n + ": depth and speed sizes differ");
    for (std::size_t i = 0; i < c.depth_m.size() && i < c.speed_mps.size(); ++i) {
        const double d = c.depth_m[i], v = c.speed_mps[i];
        if (!(d >= -1.0 && d <= 12000.0)) p.push_back(n + ": depth outside [-1, 12000] m");
        if (!(v >= kMinSpeedMps && v <= kMaxSpeedMps)) p.push_back(n + ": speed out of range");
        if (i > 0 && !(d > c.depth_m[i - 1])) p.push_back(n + ": depths not increasing");
    }
    if (c.has_position() && !(std::abs(c.latitude_deg) <= 90 && std::abs(c.longitude_deg) <= 180)) {
        p.push_back(n + ": position out of range");
    }
    return p;
}

namespace {

std::string Sexagesimal(double deg, int degree_digits) {
    const char sign = deg < 0 ? '-' : ' ';
    double a = std::abs(deg);
    int d = static_cast<int>(a);
    int m = static_cast<int>((a - d) * 60.0);
    double s = ((a - d) * 60.0 - m) * 60.0;
    if (s >= 59.995) {
        s = 0;
        if (++m == 60) {
            m = 0;
            ++d;
        }
    }
    char buf[48];
    std::snprintf(buf, sizeof(buf), "%c%0*d:%02d:%05.2f", sign, degree_digits, d, m, s);
    std::string out(buf);
    return out.front() == ' ' ? out.substr(1) : out;
}

}  // namespace

std::string FormatCarisSvp(const std::vector<SoundSpeedCast>& casts, const std::string& file_name) {
    std::string out = "[SVP_VERSION_2]\n" + file_name + "\n";
    for (const SoundSpeedCast& c : casts) {
        const std::int64_t unix = UnixFromGps(c.utime_gps);
        const UtcCalendar cal = UtcCalendarFromUnix(unix);
        UtcCalendar jan1;
        jan1.year = cal.year;
        const auto start = UnixFromUtcCalendar(jan1);
        const int doy = start ? static_cast<int>((unix - *start) / 86400000000LL) + 1 : 1;
        char buf[160];
        std::snprintf(buf,
                      sizeof(buf),
                      "Section %04d-%03d %02d:%02d:%02d %s %s\n",
                      cal.year,
                      doy,
                      cal.hour,
                      cal.minute,
                      cal.second,
                      Sexagesimal(c.has_position() ? c.latitude_deg : 0.0, 2).c_str(),
                      Sexagesimal(c.has_position() ? c.longitude_deg : 0.0, 3).c_str());
        out += buf;
        for (std::size_t i = 0; i < c.depth_m.size(); ++i) {
            std::snprintf(buf, sizeof(buf), "%.3f %.3f\n", c.depth_m[i], c.speed_mps[i]);
            out += buf;
        }
    }
    return out;
}

}  // namespace pitmap::proc::svp
