// SPDX-License-Identifier: MIT
#include "processor/svp/probe_casts.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <optional>
#include <tuple>
#include <utility>

#include "common/gps_time.hpp"
#include "common/text.hpp"
#include "processor/svp/seawater.hpp"

namespace pitmap::proc::svp {

namespace {

using text::ParseNumber;
using text::TrimBlanks;

constexpr double kDefaultLatitudeDeg = 45.0;

struct Line {
    std::string_view text;  // without the '\n', blanks trimmed
    int number = 0;         // 1-based
};

std::vector<Line> SplitLines(std::string_view text) {
    std::vector<Line> out;
    std::size_t pos = 0;
    int n = 0;
    while (pos < text.size()) {
        std::size_t end = text.find('\n', pos);
        if (end == std::string_view::npos) end = text.size();
        out.push_back({TrimBlanks(text.substr(pos, end - pos)), ++n});
        pos = end + 1;
    }
    return out;
}

std::vector<std::string_view> Split(std::string_view s, char sep) {
    std::vector<std::string_view> out;
    std::size_t start = 0;
    for (std::size_t i = 0; i <= s.size(); ++i) {
        if (i == s.size() || s[i] == sep) {
            out.push_back(TrimBlanks(s.substr(start, i - start)));
            start = i + 1;
        }
    }
    return out;
}

std::vector<std::string_view> SplitWhitespace(std::string_view s) {
    std::vector<std::string_view> out;
    std::size_t i = 0;
    auto blank = [](char c) { return c == ' ' || c == '\t' || c == '\r'; };
    while (i < s.size()) {
        while (i < s.size() && blank(s[i])) ++i;
        std::size_t j = i;
        while (j < s.size() && !blank(s[j])) ++j;
        if (j > i) out.push_back(s.substr(i, j - i));
        i = j;
    }
    return out;
}

bool StartsWith(std::string_view s, std::string_view prefix) {
    return s.substr(0, prefix.size()) == prefix;
}

std::string Upper(std::string_view s) {
    std::string out(s);
    for (char& c : out) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    return out;
}

std::string Quoted(std::string_view s) {
    std::string out = "'";
    for (char c : s.substr(0, 40)) out += (c >= 32 && c < 127) ? c : '?';
    if (s.size() > 40) out += "...";
    return out + "'";
}

Error At(const std::string& name, int line, const std::string& what) {
    return Error{name + ":" + std::to_string(line) + ": " + what};
}

std::optional<int> Digits(std::string_view s, std::size_t min_digits, std::size_t max_digits) {
    if (s.size() < min_digits || s.size() > max_digits) return std::nullopt;
    int v = 0;
    for (char c : s) {
        if (c < '0' || c > '9') return std::nullopt;
        v = v * 10 + (c - '0');
    }
    return v;
}

// GPS microseconds of a UTC civil time; nullopt when a field is out of range.
std::optional<std::int64_t> GpsAt(int y, int mo, int d, int h, int mi, double sec) {
    if (y < 1980 || y > 2200 || h < 0 || h > 23 || mi < 0 || mi > 59 || !(sec >= 0 && sec < 61)) {
        return std::nullopt;
    }
    UtcCalendar c;
    c.year = y;
    c.month = mo;
    c.day = d;
    const auto midnight = UnixFromUtcCalendar(c);
    if (!midnight) return std::nullopt;
    const double s = h * 3600.0 + mi * 60.0 + sec;
    return GpsFromUnix(*midnight + static_cast<std::int64_t>(std::llround(s * 1e6)));
}

// "HH:MM[:SS[.ss]]" -> hour, minute, seconds.
std::optional<std::tuple<int, int, double>> ClockTime(std::string_view s) {
    const auto p = Split(s, ':');
    if (p.size() < 2 || p.size() > 3) return std::nullopt;
    const auto h = Digits(p[0], 1, 2);
    const auto m = Digits(p[1], 1, 2);
    const auto sec = p.size() == 3 ? ParseNumber(p[2]) : std::optional<double>(0.0);
    if (!h || !m || !sec) return std::nullopt;
    return std::tuple<int, int, double>{*h, *m, *sec};
}

// "YYYY-MM-DD" and "HH:MM:SS.ss".
std::optional<std::int64_t> GpsFromIsoParts(std::string_view date, std::string_view time) {
    const auto d = Split(date, '-');
    const auto t = ClockTime(time);
    if (d.size() != 3 || !t) return std::nullopt;
    const auto y = Digits(d[0], 4, 4);
    const auto mo = Digits(d[1], 1, 2);
    const auto day = Digits(d[2], 1, 2);
    if (!y || !mo || !day) return std::nullopt;
    return GpsAt(*y, *mo, *day, std::get<0>(*t), std::get<1>(*t), std::get<2>(*t));
}

// "A/B/YYYY": day first unless A cannot be a day of a month... B > 12 means month first.
std::optional<std::int64_t> GpsFromSlashDate(std::string_view date,
                                             std::string_view time,
                                             bool month_first) {
    const auto d = Split(date, '/');
    const auto t = ClockTime(time);
    if (d.size() != 3 || !t) return std::nullopt;
    const auto a = Digits(d[0], 1, 2);
    const auto b = Digits(d[1], 1, 2);
    const auto y = Digits(d[2], 4, 4);
    if (!a || !b || !y) return std::nullopt;
    int day = month_first ? *b : *a;
    int month = month_first ? *a : *b;
    if (month > 12 && day <= 12) std::swap(day, month);
    return GpsAt(*y, month, day, std::get<0>(*t), std::get<1>(*t), std::get<2>(*t));
}

std::optional<int> MonthFromName(std::string_view s) {
    static constexpr const char* kMonths[] = {
        "JAN", "FEB", "MAR", "APR", "MAY", "JUN", "JUL", "AUG", "SEP", "OCT", "NOV", "DEC"};
    const std::string u = Upper(s.substr(0, 3));
    for (int i = 0; i < 12; ++i) {
        if (u == kMonths[i]) return i + 1;
    }
    return std::nullopt;
}

// Sets the position unless it is 0 0 (unknown); false when out of range.
bool SetPosition(SoundSpeedCast& c, double lat, double lon) {
    if (!(std::abs(lat) <= 90.0 && std::abs(lon) <= 180.0)) return false;
    if (lat == 0.0 && lon == 0.0) return true;
    c.latitude_deg = lat;
    c.longitude_deg = lon;
    return true;
}

// The valid samples of a probe file (rule 1 applied as they come).
struct Samples {
    std::vector<double> depth_m;
    std::vector<double> speed_mps;
    ProbeCastStats& stats;

    void Add(double depth, double speed) {
        ++stats.rows;
        if (!(depth >= -1.0 && depth <= 12000.0 && speed >= kMinSpeedMps &&
              speed <= kMaxSpeedMps)) {
            ++stats.invalid;
            return;
        }
        depth_m.push_back(depth);
        speed_mps.push_back(speed);
    }
    void AddInvalid() {
        ++stats.rows;
        ++stats.invalid;
    }
};

Expected<SoundSpeedCast> Finish(SoundSpeedCast c, const Samples& s, const std::string& name) {
    if (s.depth_m.empty()) {
        if (s.stats.rows == 0) return Error{name + ": no data rows (the file ends early?)"};
        return Error{name + ": none of the " + std::to_string(s.stats.rows) +
                     " rows has a depth in [-1, 12000] m and a sound speed in [1300, 1800] m/s"};
    }
    const auto keep = DownCast(s.depth_m, &s.stats);
    if (keep.size() > kMaxCastPoints) {
        return Error{name + ": more than " + std::to_string(kMaxCastPoints) +
                     " points in one cast"};
    }
    c.name = name;
    for (std::size_t i : keep) {
        c.depth_m.push_back(s.depth_m[i]);
        c.speed_mps.push_back(s.speed_mps[i]);
    }
    return c;
}

double Latitude(const SoundSpeedCast& c) {
    return c.has_position() ? c.latitude_deg : kDefaultLatitudeDeg;
}

// --- AML Base.X2 ------------------------------------------------------------------------

Expected<SoundSpeedCast> ParseAml(std::string_view text,
                                  const std::string& name,
                                  ProbeCastStats& st) {
    SoundSpeedCast c;
    Samples s{{}, {}, st};
    std::string section;
    std::string_view date, time;
    std::optional<double> lat[2], lon[2];  // [Instrument], [Data.X]
    int lat_line[2] = {0, 0};
    std::vector<std::pair<double, int>> pressures;  // pressure, line (depth needs the latitude)
    std::vector<double> speeds;
    std::optional<std::int64_t> first_row_time;
    int first_row_line = 0;
    std::size_t first_row_fields = 0;
    bool data = false;
    for (const Line& l : SplitLines(text)) {
        if (l.text.empty()) continue;
        if (l.text.front() == '[' && l.text.back() == ']') {
            section = Upper(l.text);
            data = section == "[DATA]";
            continue;
        }
        if (!data) {
            const std::size_t eq = l.text.find('=');
            if (eq == std::string_view::npos) continue;
            const std::string_view key = TrimBlanks(l.text.substr(0, eq));
            const std::string_view value = TrimBlanks(l.text.substr(eq + 1));
            const int slot = section == "[DATA.X]" ? 1 : 0;
            if (section == "[INSTRUMENT]" && key == "Date") date = value;
            if (section == "[INSTRUMENT]" && key == "Time") time = value;
            if ((section == "[INSTRUMENT]" || slot == 1) &&
                (key == "Latitude" || key == "Longitude")) {
                const auto v = ParseNumber(value);
                if (!v)
                    return At(name,
                              l.number,
                              std::string(key) + " " + Quoted(value) + " is not a number");
                (key == "Latitude" ? lat : lon)[slot] = *v;
                lat_line[slot] = l.number;
            }
            continue;
        }
        const auto f = Split(l.text, ',');
        if (first_row_line > 0 && f.size() != first_row_fields) {
            return At(name,
                      l.number,
                      std::to_string(f.size()) + " fields, the first row (line " +
                          std::to_string(first_row_line) + ") has " +
                          std::to_string(first_row_fields));
        }
        if (first_row_line == 0) {
            first_row_line = l.number;
            first_row_fields = f.size();
        }
        if (f.size() < 4) {
            return At(
                name, l.number, "expected 'date,time,speed,pressure[,...]', got " + Quoted(l.text));
        }
        const auto t = GpsFromIsoParts(f[0], f[1]);
        if (!t)
            return At(
                name, l.number, "date and time " + Quoted(l.text) + " are not YYYY-MM-DD,HH:MM:SS");
        if (!first_row_time) first_row_time = t;
        const auto v = ParseNumber(f[2]);
        const auto p = ParseNumber(f[3]);
        if (!v) return At(name, l.number, "sound speed " + Quoted(f[2]) + " is not a number");
        if (!p) return At(name, l.number, "pressure " + Quoted(f[3]) + " is not a number");
        pressures.push_back({*p, l.number});
        speeds.push_back(*v);
    }
    if (section.empty()) return Error{name + ": no [cast header]: not an AML file"};
    for (int slot : {1, 0}) {
        if (lat[slot] && lon[slot]) {
            if (!SetPosition(c, *lat[slot], *lon[slot])) {
                return At(name, lat_line[slot], "position out of range");
            }
            if (c.has_position()) break;
        }
    }
    if (!date.empty() || !time.empty()) {
        const auto t = GpsFromIsoParts(date, time);
        if (!t) {
            return Error{name + ": header Date=" + std::string(date) +
                         " Time=" + std::string(time) + " is not YYYY-MM-DD HH:MM:SS"};
        }
        c.utime_gps = *t;
    } else if (first_row_time) {
        c.utime_gps = *first_row_time;
    }
    if (!data) return Error{name + ": no [data] section (the file ends in its header?)"};
    st.depth_from_pressure = true;
    for (std::size_t i = 0; i < speeds.size(); ++i) {
        s.Add(DepthFromPressureUnesco(pressures[i].first, Latitude(c)), speeds[i]);
    }
    return Finish(std::move(c), s, name);
}

// --- Columns by name (CastAway, Valeport) -----------------------------------------------------

struct CtdRow {
    std::optional<double> depth_m, pressure_dbar, speed_mps, temperature_c, salinity,
        conductivity_ms_cm;
};

// The row's values from the fields: col[k] is the field of depth, pressure, speed, temperature,
// salinity, conductivity (k = 0..5; -1 = no such column), read from k = first on. "" or the
// problem.
std::string ReadColumns(const std::vector<std::string_view>& f,
                        const int (&col)[6],
                        int first,
                        CtdRow& r) {
    std::optional<double>* dst[6] = {&r.depth_m,
                                     &r.pressure_dbar,
                                     &r.speed_mps,
                                     &r.temperature_c,
                                     &r.salinity,
                                     &r.conductivity_ms_cm};
    for (int k = first; k < 6; ++k) {
        if (col[k] < 0) continue;
        const std::string_view v = f[static_cast<std::size_t>(col[k])];
        *dst[k] = ParseNumber(v);
        if (!*dst[k]) return "value " + Quoted(v) + " is not a number";
    }
    return "";
}

// Depth and speed of a row (UNESCO and Chen & Millero where a column is missing), or nullopt
// when a needed value is missing.
std::optional<std::pair<double, double>> DepthSpeed(const CtdRow& r, double latitude_deg) {
    std::optional<double> depth = r.depth_m;
    if (!depth && r.pressure_dbar) depth = DepthFromPressureUnesco(*r.pressure_dbar, latitude_deg);
    if (!depth) return std::nullopt;
    if (r.speed_mps) return std::pair<double, double>{*depth, *r.speed_mps};
    if (!r.temperature_c) return std::nullopt;
    // Without a pressure column, 1 dbar per metre (the pressure term is small near the surface).
    const double p = r.pressure_dbar ? *r.pressure_dbar : *depth;
    double sal = 0;
    if (r.salinity) {
        sal = *r.salinity;
    } else if (r.conductivity_ms_cm) {
        sal = SalinityFromConductivity(*r.conductivity_ms_cm, *r.temperature_c, p);
    } else {
        return std::nullopt;
    }
    return std::pair<double, double>{*depth, SoundSpeedChenMillero(sal, *r.temperature_c, p)};
}

// --- SonTek CastAway -----------------------------------------------------------------------

Expected<SoundSpeedCast> ParseCastAway(std::string_view text,
                                       const std::string& name,
                                       ProbeCastStats& st) {
    SoundSpeedCast c;
    Samples s{{}, {}, st};
    std::optional<double> lat, lon;
    int lat_line = 0;
    // Column indices: depth, pressure, speed, temperature, salinity, conductivity.
    int col[6] = {-1, -1, -1, -1, -1, -1};
    std::size_t columns = 0;
    int header_line = 0;
    for (const Line& l : SplitLines(text)) {
        if (l.text.empty()) continue;
        if (l.text.front() == '%') {
            const std::string_view kv = TrimBlanks(l.text.substr(1));
            const std::size_t comma = kv.find(',');
            if (comma == std::string_view::npos) continue;
            const std::string_view key = TrimBlanks(kv.substr(0, comma));
            const std::string_view value = TrimBlanks(kv.substr(comma + 1));
            if (key == "Cast time (UTC)") {
                const auto f = SplitWhitespace(value);
                const auto t = f.size() == 2 ? GpsFromIsoParts(f[0], f[1]) : std::nullopt;
                if (!t) {
                    return At(name,
                              l.number,
                              "cast time " + Quoted(value) + " is not YYYY-MM-DD HH:MM:SS");
                }
                c.utime_gps = *t;
            } else if (key == "Start latitude" || key == "Start longitude") {
                // An empty or NaN value: no GPS fix at the start.
                const auto v = ParseNumber(value);
                if (!v && !value.empty() && Upper(value) != "NAN") {
                    return At(name,
                              l.number,
                              std::string(key) + " " + Quoted(value) + " is not a number");
                }
                (key == "Start latitude" ? lat : lon) = v;
                lat_line = l.number;
            }
            continue;
        }
        const auto f = Split(l.text, ',');
        if (header_line == 0) {
            header_line = l.number;
            columns = f.size();
            for (std::size_t i = 0; i < f.size(); ++i) {
                const int ii = static_cast<int>(i);
                if (StartsWith(f[i], "Depth")) col[0] = ii;
                if (StartsWith(f[i], "Pressure")) col[1] = ii;
                if (StartsWith(f[i], "Sound velocity") || StartsWith(f[i], "Sound speed"))
                    col[2] = ii;
                if (StartsWith(f[i], "Temperature")) col[3] = ii;
                if (StartsWith(f[i], "Salinity")) col[4] = ii;
                if (StartsWith(f[i], "Conductivity")) col[5] = ii;
            }
            if (col[0] < 0 && col[1] < 0) {
                return At(name, l.number, "no 'Depth' or 'Pressure' column in " + Quoted(l.text));
            }
            if (col[2] < 0 && (col[3] < 0 || (col[4] < 0 && col[5] < 0))) {
                return At(name,
                          l.number,
                          "no 'Sound velocity' column, and no 'Temperature' with 'Salinity' or "
                          "'Conductivity' to compute it");
            }
            st.speed_computed = col[2] < 0;
            st.depth_from_pressure = col[0] < 0;
            continue;
        }
        if (f.size() != columns) {
            return At(name,
                      l.number,
                      std::to_string(f.size()) + " fields, the column header (line " +
                          std::to_string(header_line) + ") has " + std::to_string(columns));
        }
        CtdRow r;
        if (const std::string bad = ReadColumns(f, col, 0, r); !bad.empty())
            return At(name, l.number, bad);
        if (r.conductivity_ms_cm) *r.conductivity_ms_cm /= 1000.0;  // uS/cm
        if (lat && lon && !c.has_position() && !SetPosition(c, *lat, *lon)) {
            return At(name, lat_line, "start position out of range");
        }
        const auto ds = DepthSpeed(r, Latitude(c));
        if (ds) {
            s.Add(ds->first, ds->second);
        } else {
            s.AddInvalid();
        }
    }
    if (lat && lon && !c.has_position() && !SetPosition(c, *lat, *lon)) {
        return At(name, lat_line, "start position out of range");
    }
    if (header_line == 0)
        return Error{name + ": no column header after the '%' lines (truncated?)"};
    return Finish(std::move(c), s, name);
}

// --- HYPACK .vel and Kongsberg .asvp: a header line, then `depth speed` -------------------

Expected<SoundSpeedCast> ParseDepthSpeedRows(const std::vector<Line>& lines,
                                             std::size_t first,
                                             const std::string& name,
                                             SoundSpeedCast c,
                                             ProbeCastStats& st) {
    Samples s{{}, {}, st};
    for (std::size_t i = first; i < lines.size(); ++i) {
        const Line& l = lines[i];
        if (l.text.empty()) continue;
        const auto f = SplitWhitespace(l.text);
        if (f.size() < 2)
            return At(name, l.number, "expected 'depth speed', got " + Quoted(l.text));
        const auto d = ParseNumber(f[0]);
        const auto v = ParseNumber(f[1]);
        if (!d) return At(name, l.number, "depth " + Quoted(f[0]) + " is not a number");
        if (!v) return At(name, l.number, "sound speed " + Quoted(f[1]) + " is not a number");
        s.Add(*d, *v);
    }
    return Finish(std::move(c), s, name);
}

Expected<SoundSpeedCast> ParseHypack(std::string_view text,
                                     const std::string& name,
                                     ProbeCastStats& st) {
    const auto lines = SplitLines(text);
    SoundSpeedCast c;
    const auto h = SplitWhitespace(lines.front().text);
    if (h.size() < 3 || h[0] != "FTP") return At(name, 1, "not a HYPACK 'FTP NEW' header");
    if (h.size() >= 5) {
        const auto lat = ParseNumber(h[3]);
        const auto lon = ParseNumber(h[4]);
        if (!lat || !lon || !SetPosition(c, *lat, *lon)) {
            return At(name,
                      1,
                      "position " + Quoted(std::string(h[3]) + " " + std::string(h[4])) +
                          " is not LAT LON in degrees");
        }
    }
    if (h.size() >= 7) {
        const auto t = GpsFromSlashDate(h[6], h[5], true);
        if (!t) {
            return At(name,
                      1,
                      "time " + Quoted(std::string(h[5]) + " " + std::string(h[6])) +
                          " is not HH:MM MM/DD/YYYY");
        }
        c.utime_gps = *t;
    }
    return ParseDepthSpeedRows(lines, 1, name, std::move(c), st);
}

Expected<SoundSpeedCast> ParseAsvp(std::string_view text,
                                   const std::string& name,
                                   ProbeCastStats& st) {
    const auto lines = SplitLines(text);
    SoundSpeedCast c;
    const auto h = SplitWhitespace(lines.front().text);
    if (h.size() < 8 || h[0] != "(" || h[1] != "SoundVelocity" || h.back() != ")") {
        return At(name, 1, "expected '( SoundVelocity 1.0 0 YYYYMMDDHHMM LAT LON ... N )'");
    }
    const std::string_view ts = h[4].size() == 12 ? h[4] : std::string_view("x           ");
    const auto y = Digits(ts.substr(0, 4), 4, 4);
    const auto mo = Digits(ts.substr(4, 2), 2, 2);
    const auto d = Digits(ts.substr(6, 2), 2, 2);
    const auto hh = Digits(ts.substr(8, 2), 2, 2);
    const auto mi = Digits(ts.substr(10), 2, 2);
    const auto t = (y && mo && d && hh && mi) ? GpsAt(*y, *mo, *d, *hh, *mi, 0) : std::nullopt;
    if (!t) return At(name, 1, "time " + Quoted(ts) + " is not YYYYMMDDHHMM");
    c.utime_gps = *t;
    const auto lat = ParseNumber(h[5]);
    const auto lon = ParseNumber(h[6]);
    if (!lat || !lon || !SetPosition(c, *lat, *lon)) {
        return At(name,
                  1,
                  "position " + Quoted(std::string(h[5]) + " " + std::string(h[6])) +
                      " is not LAT LON in degrees");
    }
    const auto n = Digits(h[h.size() - 2], 1, 6);
    if (!n) return At(name, 1, "number of points " + Quoted(h[h.size() - 2]) + " is not a count");
    auto r = ParseDepthSpeedRows(lines, 1, name, std::move(c), st);
    if (r && st.rows != static_cast<std::size_t>(*n)) {
        return Error{name + ": " + std::to_string(st.rows) + " points, the header declares " +
                     std::to_string(*n) + " (truncated?)"};
    }
    return r;
}

// --- Simrad $xxS10 / $xxS12 ------------------------------------------------------------------

Expected<SoundSpeedCast> ParseSimrad(std::string_view text,
                                     const std::string& name,
                                     bool s12,
                                     ProbeCastStats& st) {
    const auto lines = SplitLines(text);
    std::vector<std::pair<std::string_view, int>> tok;  // field, line
    bool ended = false;
    int last_line = 0;
    for (const Line& l : lines) {
        if (l.text.empty()) continue;
        if (ended) return At(name, l.number, "text after the end of the sentence ('\\')");
        if (l.text == "\\") {
            ended = true;
            continue;
        }
        std::string_view body = l.text;
        bool closes = false;
        if (body.back() == '\\') {
            body.remove_suffix(1);
            closes = true;
        }
        const bool trailing_comma = !body.empty() && body.back() == ',';
        if (trailing_comma) body.remove_suffix(1);
        for (std::string_view f : Split(body, ',')) tok.push_back({f, l.number});
        last_line = l.number;
        ended = closes;
    }
    if (!ended) {
        return Error{name + ": the sentence has no end ('\\' after the last field): truncated?"};
    }
    if (tok.size() < 7) return At(name, last_line, "the sentence header needs 7 fields");
    // The checksum "*hh" ends the last field of an S12; it is dropped, not checked.
    auto& back = tok.back().first;
    if (const std::size_t star = back.find('*'); star != std::string_view::npos) {
        back = back.substr(0, star);
    }
    const auto n = Digits(tok[2].first, 1, 6);
    if (!n || *n == 0)
        return At(
            name, tok[2].second, "number of points " + Quoted(tok[2].first) + " is not a count");
    const std::string_view hms =
        tok[3].first.size() == 6 ? tok[3].first : std::string_view("x     ");
    const auto hh = Digits(hms.substr(0, 2), 2, 2);
    const auto mm = Digits(hms.substr(2, 2), 2, 2);
    const auto ss = Digits(hms.substr(4), 2, 2);
    const auto dd = Digits(tok[4].first, 1, 2);
    const auto mo = Digits(tok[5].first, 1, 2);
    const auto yy = Digits(tok[6].first, 4, 4);
    const auto t =
        (hh && mm && ss && dd && mo && yy) ? GpsAt(*yy, *mo, *dd, *hh, *mm, *ss) : std::nullopt;
    if (!t) return At(name, tok[3].second, "time 'hhmmss,dd,mm,yyyy' does not parse");
    SoundSpeedCast c;
    c.utime_gps = *t;
    const std::size_t trailer = s12 ? 6 : 0;
    const std::size_t values = tok.size() - 7;
    const std::size_t per =
        values >= trailer ? (values - trailer) / static_cast<std::size_t>(*n) : 0;
    if (values < trailer || per < 2 || per * static_cast<std::size_t>(*n) + trailer != values) {
        return At(name,
                  last_line,
                  std::to_string(values) + " fields after the header do not hold the " +
                      std::to_string(*n) + " points it declares" +
                      (s12 ? " and the position" : "") + " (truncated?)");
    }
    if (s12) {
        const std::size_t k = tok.size() - trailer;
        const auto lat = ParseNumber(tok[k].first);
        const auto lon = ParseNumber(tok[k + 2].first);
        const std::string_view ns = tok[k + 1].first, ew = tok[k + 3].first;
        if (!lat || !lon || (ns != "N" && ns != "S") || (ew != "E" && ew != "W")) {
            return At(name, tok[k].second, "position is not 'ddmm.mm,N,dddmm.mm,W'");
        }
        auto deg = [](double v) { return std::floor(v / 100.0) + std::fmod(v, 100.0) / 60.0; };
        if (!SetPosition(c, (ns == "S" ? -1 : 1) * deg(*lat), (ew == "W" ? -1 : 1) * deg(*lon))) {
            return At(name, tok[k].second, "position out of range");
        }
    }
    Samples s{{}, {}, st};
    for (std::size_t i = 0; i < static_cast<std::size_t>(*n); ++i) {
        const auto& fd = tok[7 + i * per];
        const auto& fv = tok[8 + i * per];
        const auto d = ParseNumber(fd.first);
        const auto v = ParseNumber(fv.first);
        if (!d) return At(name, fd.second, "depth " + Quoted(fd.first) + " is not a number");
        if (!v) return At(name, fv.second, "sound speed " + Quoted(fv.first) + " is not a number");
        s.Add(*d, *v);
    }
    return Finish(std::move(c), s, name);
}

// --- Sea-Bird .cnv ---------------------------------------------------------------------------

// "43 02.88 N" -> degrees.
std::optional<double> NmeaAngle(std::string_view s) {
    const auto f = SplitWhitespace(s);
    if (f.size() != 3) return std::nullopt;
    const auto d = ParseNumber(f[0]);
    const auto m = ParseNumber(f[1]);
    if (!d || !m || *d < 0 || *m < 0 || *m >= 60) return std::nullopt;
    const double v = *d + *m / 60.0;
    if (f[2] == "S" || f[2] == "W") return -v;
    if (f[2] == "N" || f[2] == "E") return v;
    return std::nullopt;
}

// "Mar 07 2013 20:01:53" (month first) or "07 Mar 2013 20:01:53" (day first).
std::optional<std::int64_t> SeaBirdTime(const std::vector<std::string_view>& f, std::size_t i) {
    if (f.size() < i + 4) return std::nullopt;
    auto mo = MonthFromName(f[i]);
    auto d = Digits(f[i + 1], 1, 2);
    if (!mo) {
        mo = MonthFromName(f[i + 1]);
        d = Digits(f[i], 1, 2);
    }
    const auto y = Digits(f[i + 2], 4, 4);
    const auto t = ClockTime(f[i + 3]);
    if (!mo || !d || !y || !t) return std::nullopt;
    return GpsAt(*y, *mo, *d, std::get<0>(*t), std::get<1>(*t), std::get<2>(*t));
}

// What a .cnv header says: position and times, the columns, and where the data start.
struct SeaBirdHeader {
    std::optional<std::int64_t> nmea_time, cast_time, start_time;
    std::optional<double> lat, lon;
    int lat_line = 0;
    std::optional<int> nquan;
    std::optional<double> bad_flag;
    std::vector<std::pair<int, std::string>> names;  // index, short name
    bool end = false;                                // the '*END*' line was seen
    std::size_t data_line = 0;                       // the first line after it
};

// One '*' or '#' header line's key and value into h; an error for a malformed value.
std::optional<Error> ReadSeaBirdHeaderLine(const Line& l,
                                           const std::string& name,
                                           SeaBirdHeader& h) {
    const std::string_view body = TrimBlanks(l.text.substr(1));
    const std::size_t eq = body.find('=');
    const std::string_view key =
        eq == std::string_view::npos ? body : TrimBlanks(body.substr(0, eq));
    const std::string_view value =
        eq == std::string_view::npos ? std::string_view() : TrimBlanks(body.substr(eq + 1));
    if (key == "NMEA Latitude" || key == "NMEA Longitude") {
        const auto v = NmeaAngle(value);
        if (!v)
            return At(
                name, l.number, std::string(key) + " " + Quoted(value) + " is not 'dd mm.mm N'");
        (key == "NMEA Latitude" ? h.lat : h.lon) = v;
        h.lat_line = l.number;
    } else if (key == "NMEA UTC (Time)") {
        h.nmea_time = SeaBirdTime(SplitWhitespace(value), 0);
        if (!h.nmea_time)
            return At(name, l.number, "NMEA UTC time " + Quoted(value) + " does not parse");
    } else if (key == "nquan") {
        const auto v = Digits(value, 1, 3);
        if (!v || *v == 0) return At(name, l.number, "nquan " + Quoted(value) + " is not a count");
        h.nquan = *v;
    } else if (key == "bad_flag") {
        h.bad_flag = ParseNumber(value);
    } else if (StartsWith(key, "name ")) {
        const auto idx = Digits(TrimBlanks(key.substr(5)), 1, 3);
        const std::size_t colon = value.find(':');
        if (!idx || colon == std::string_view::npos) {
            return At(name,
                      l.number,
                      "column name line " + Quoted(l.text) + " is not 'name i = short: long'");
        }
        h.names.push_back({*idx, std::string(TrimBlanks(value.substr(0, colon)))});
    } else if (key == "start_time") {
        if (Upper(value).find("UPLOAD") == std::string::npos) {
            h.start_time = SeaBirdTime(SplitWhitespace(value), 0);
        }
    } else if (l.text.front() == '*' && !h.cast_time) {
        // "* S>* cast   2 07 Mar 2013 20:01:53 samples 722 to 2030, ..."
        const auto f = SplitWhitespace(body);
        for (std::size_t k = 0; k + 1 < f.size(); ++k) {
            if (f[k] == "cast" || StartsWith(f[k], "S>*cast")) {
                h.cast_time = SeaBirdTime(f, k + 2);
                break;
            }
        }
    }
    return std::nullopt;
}

// The header up to '*END*'; an error for data before it or a malformed line.
Expected<SeaBirdHeader> ReadSeaBirdHeader(const std::vector<Line>& lines, const std::string& name) {
    SeaBirdHeader h;
    std::size_t i = 0;
    for (; i < lines.size(); ++i) {
        const Line& l = lines[i];
        if (l.text == "*END*") {
            h.end = true;
            ++i;
            break;
        }
        if (l.text.empty()) continue;
        if (l.text.front() != '*' && l.text.front() != '#') {
            return At(name, l.number, "data before '*END*': " + Quoted(l.text));
        }
        if (auto e = ReadSeaBirdHeaderLine(l, name, h)) return *e;
    }
    h.data_line = i;
    return h;
}

// The columns a cast is made of: depth, pressure, speed, temperature, salinity, conductivity,
// flag (-1: absent), with the temperature's scale to ITS-90 and the conductivity's to mS/cm.
struct SeaBirdColumns {
    int col[7] = {-1, -1, -1, -1, -1, -1, -1};
    double t_scale = 1.0, c_scale = 1.0;
};

Expected<SeaBirdColumns> FindSeaBirdColumns(const SeaBirdHeader& h, const std::string& name) {
    SeaBirdColumns sc;
    int* col = sc.col;
    for (const auto& [idx, sn] : h.names) {
        if (idx >= *h.nquan) return Error{name + ": column " + std::to_string(idx) + " >= nquan"};
        if (StartsWith(sn, "depS") || StartsWith(sn, "depF")) col[0] = idx;
        if (StartsWith(sn, "pr")) col[1] = idx;
        if (StartsWith(sn, "sv") && col[2] < 0) col[2] = idx;
        if ((StartsWith(sn, "t090") || StartsWith(sn, "t190") || StartsWith(sn, "tv290") ||
             StartsWith(sn, "t068")) &&
            col[3] < 0) {
            col[3] = idx;
            sc.t_scale = StartsWith(sn, "t068") ? 1.0 / 1.00024 : 1.0;
        }
        if (StartsWith(sn, "sal") && col[4] < 0) col[4] = idx;
        if ((StartsWith(sn, "c0") || StartsWith(sn, "c1")) && col[5] < 0) {
            col[5] = idx;
            sc.c_scale = sn.find("uS/cm") != std::string::npos   ? 1e-3
                         : sn.find("mS/cm") != std::string::npos ? 1.0
                                                                 : 10.0;  // S/m
        }
        if (sn == "flag") col[6] = idx;
    }
    if (col[0] < 0 && col[1] < 0)
        return Error{name + ": no depth (depS, depF) or pressure (pr*) column"};
    if (col[2] < 0 && (col[3] < 0 || (col[4] < 0 && col[5] < 0))) {
        return Error{name +
                     ": no sound speed (sv*) column, and no temperature with salinity or "
                     "conductivity to compute it"};
    }
    return sc;
}

// The data rows into s: each row's depth and speed (computed from the CTD columns where the
// file has no speed), bad-flagged rows counted invalid. An error for a row of the wrong width or
// a value that is not a number.
std::optional<Error> ReadSeaBirdRows(const std::vector<Line>& lines,
                                     const SeaBirdHeader& h,
                                     const SeaBirdColumns& sc,
                                     double latitude,
                                     const std::string& name,
                                     Samples& s) {
    const int* col = sc.col;
    for (std::size_t i = h.data_line; i < lines.size(); ++i) {
        const Line& l = lines[i];
        if (l.text.empty()) continue;
        const auto f = SplitWhitespace(l.text);
        if (f.size() != static_cast<std::size_t>(*h.nquan)) {
            return At(name,
                      l.number,
                      std::to_string(f.size()) + " values, the header names " +
                          std::to_string(*h.nquan) + " (a truncated row?)");
        }
        std::vector<double> v(f.size());
        bool bad = false;
        for (std::size_t k = 0; k < f.size(); ++k) {
            const auto x = ParseNumber(f[k]);
            if (!x) return At(name, l.number, "value " + Quoted(f[k]) + " is not a number");
            v[k] = *x;
            if (h.bad_flag && *x == *h.bad_flag) bad = true;
        }
        if (col[6] >= 0 && v[static_cast<std::size_t>(col[6])] != 0.0) bad = true;
        if (bad) {
            s.AddInvalid();
            continue;
        }
        auto get = [&](int k) -> std::optional<double> {
            if (k < 0) return std::nullopt;
            return v[static_cast<std::size_t>(k)];
        };
        CtdRow r{get(col[0]), get(col[1]), get(col[2]), get(col[3]), get(col[4]), get(col[5])};
        if (r.temperature_c) *r.temperature_c *= sc.t_scale;
        if (r.conductivity_ms_cm) *r.conductivity_ms_cm *= sc.c_scale;
        const auto ds = DepthSpeed(r, latitude);
        if (ds) {
            s.Add(ds->first, ds->second);
        } else {
            s.AddInvalid();
        }
    }
    return std::nullopt;
}

Expected<SoundSpeedCast> ParseSeaBird(std::string_view text,
                                      const std::string& name,
                                      ProbeCastStats& st) {
    const auto lines = SplitLines(text);
    auto header = ReadSeaBirdHeader(lines, name);
    if (!header) return header.error();
    const SeaBirdHeader& h = *header;
    if (!h.end) return Error{name + ": no '*END*' line: the header is truncated"};
    if (!h.nquan) return Error{name + ": no '# nquan' in the header"};
    SoundSpeedCast c;
    if (h.lat && h.lon && !SetPosition(c, *h.lat, *h.lon))
        return At(name, h.lat_line, "position out of range");
    if (h.nmea_time) {
        c.utime_gps = *h.nmea_time;
    } else if (h.cast_time) {
        c.utime_gps = *h.cast_time;
    } else if (h.start_time) {
        c.utime_gps = *h.start_time;
    }
    const auto columns = FindSeaBirdColumns(h, name);
    if (!columns) return columns.error();
    st.speed_computed = columns->col[2] < 0;
    st.depth_from_pressure = columns->col[0] < 0;
    Samples s{{}, {}, st};
    if (auto e = ReadSeaBirdRows(lines, h, *columns, Latitude(c), name, s)) return *e;
    return Finish(std::move(c), s, name);
}

// --- Valeport MIDAS --------------------------------------------------------------------------

Expected<SoundSpeedCast> ParseValeport(std::string_view text,
                                       const std::string& name,
                                       ProbeCastStats& st) {
    const auto lines = SplitLines(text);
    SoundSpeedCast c;
    std::optional<std::int64_t> stamp;
    // Columns: depth (none), pressure, speed, temperature, salinity, conductivity.
    int col[6] = {-1, -1, -1, -1, -1, -1};
    std::size_t columns = 0;
    int header_line = 0;
    Samples s{{}, {}, st};
    auto fields = [](std::string_view t) {
        auto f = Split(t, '\t');
        while (!f.empty() && f.back().empty()) f.pop_back();
        return f;
    };
    for (const Line& l : lines) {
        if (l.text.empty()) continue;
        if (header_line == 0) {
            if (StartsWith(l.text, "Date / Time")) {
                header_line = l.number;
                const auto f = fields(l.text);
                columns = f.size();
                for (std::size_t k = 0; k < f.size(); ++k) {
                    const std::string n = Upper(TrimBlanks(f[k].substr(0, f[k].find(';'))));
                    const int kk = static_cast<int>(k);
                    if (n == "PRESSURE") col[1] = kk;
                    if (n == "SOUND VELOCITY") col[2] = kk;
                    if (n == "TEMPERATURE") col[3] = kk;
                    if (n == "CALC. SALINITY" || n == "SALINITY") col[4] = kk;
                    if (n == "CONDUCTIVITY") col[5] = kk;
                }
                if (col[1] < 0) return At(name, l.number, "no 'PRESSURE' column");
                if (col[2] < 0 && (col[3] < 0 || (col[4] < 0 && col[5] < 0))) {
                    return At(name,
                              l.number,
                              "no 'SOUND VELOCITY' column, and no 'TEMPERATURE' with salinity or "
                              "'CONDUCTIVITY' to compute it");
                }
                st.speed_computed = col[2] < 0;
                st.depth_from_pressure = true;
            } else if (StartsWith(l.text, "Time Stamp")) {
                const std::size_t colon = l.text.find(':');
                const auto f = SplitWhitespace(l.text.substr(colon + 1));
                stamp = f.size() == 2 ? GpsFromSlashDate(f[0], f[1], false) : std::nullopt;
                if (!stamp)
                    return At(name,
                              l.number,
                              "time stamp " + Quoted(l.text) + " is not DD/MM/YYYY HH:MM:SS");
            }
            continue;
        }
        const auto f = fields(l.text);
        if (f.size() != columns) {
            return At(name,
                      l.number,
                      std::to_string(f.size()) + " fields, the column header (line " +
                          std::to_string(header_line) + ") has " + std::to_string(columns));
        }
        const auto dt = SplitWhitespace(f[0]);
        const auto t = dt.size() == 2 ? GpsFromSlashDate(dt[0], dt[1], false) : std::nullopt;
        if (!t)
            return At(
                name, l.number, "date and time " + Quoted(f[0]) + " are not DD/MM/YYYY HH:MM:SS");
        if (!stamp) stamp = t;
        CtdRow r;
        if (const std::string bad = ReadColumns(f, col, 1, r); !bad.empty())
            return At(name, l.number, bad);
        const auto ds = DepthSpeed(r, kDefaultLatitudeDeg);
        if (ds) {
            s.Add(ds->first, ds->second);
        } else {
            s.AddInvalid();
        }
    }
    if (header_line == 0) return Error{name + ": no 'Date / Time' column header (truncated?)"};
    if (stamp) c.utime_gps = *stamp;
    return Finish(std::move(c), s, name);
}

}  // namespace

CastFormat SniffProbeFormat(std::string_view text) {
    std::size_t pos = 0;
    int seen = 0;
    bool first = true;
    while (pos < text.size() && seen < 400) {
        std::size_t end = text.find('\n', pos);
        if (end == std::string_view::npos) end = text.size();
        const std::string_view l = TrimBlanks(text.substr(pos, end - pos));
        pos = end + 1;
        ++seen;
        if (l.empty()) continue;
        if (first) {
            first = false;
            if (Upper(l) == "[CAST HEADER]") return CastFormat::kAml;
            if (StartsWith(l, "% Device") || StartsWith(l, "% Cast time"))
                return CastFormat::kCastAway;
            if (StartsWith(l, "FTP NEW") || StartsWith(l, "FTP OLD")) return CastFormat::kHypackVel;
            if (StartsWith(l, "( SoundVelocity") || StartsWith(l, "(SoundVelocity")) {
                return CastFormat::kKongsbergAsvp;
            }
            if (l.size() >= 7 && l[0] == '$' && l[6] == ',') {
                if (l.substr(3, 3) == "S12") return CastFormat::kSimradS12;
                if (l.substr(3, 3) == "S10") return CastFormat::kSimradS10;
            }
            if (StartsWith(l, "* Sea-Bird")) return CastFormat::kSeaBirdCnv;
            if (l.front() != '*' && l.front() != '%' && l.find(" :") == std::string_view::npos) {
                return CastFormat::kAuto;  // none of the probes' headers
            }
        }
        if (StartsWith(l, "Date / Time\t")) return CastFormat::kValeportMidas;
        if (StartsWith(l, "Model Name :") && l.find("MIDAS") != std::string_view::npos) {
            return CastFormat::kValeportMidas;
        }
        if (StartsWith(l, "# nquan")) return CastFormat::kSeaBirdCnv;
        if (StartsWith(l, "% Cast time (UTC)")) return CastFormat::kCastAway;
    }
    return CastFormat::kAuto;
}

Expected<SoundSpeedCast> ParseProbeCast(std::string_view text,
                                        const std::string& name,
                                        CastFormat format,
                                        ProbeCastStats* stats) {
    ProbeCastStats local;
    ProbeCastStats& st = stats ? *stats : local;
    st = ProbeCastStats{};
    st.format = format;
    if (TrimBlanks(text).empty()) return Error{name + ": empty sound-velocity file"};
    switch (format) {
        case CastFormat::kAml:
            return ParseAml(text, name, st);
        case CastFormat::kCastAway:
            return ParseCastAway(text, name, st);
        case CastFormat::kHypackVel:
            return ParseHypack(text, name, st);
        case CastFormat::kKongsbergAsvp:
            return ParseAsvp(text, name, st);
        case CastFormat::kSimradS12:
            return ParseSimrad(text, name, true, st);
        case CastFormat::kSimradS10:
            return ParseSimrad(text, name, false, st);
        case CastFormat::kSeaBirdCnv:
            return ParseSeaBird(text, name, st);
        case CastFormat::kValeportMidas:
            return ParseValeport(text, name, st);
        default:
            break;
    }
    return Error{name + ": " + ToString(format) + " is not a probe format"};
}

std::vector<std::size_t> DownCast(const std::vector<double>& d, ProbeCastStats* stats) {
    std::vector<std::size_t> keep;
    if (d.empty()) return keep;
    const std::size_t k =
        static_cast<std::size_t>(std::max_element(d.begin(), d.end()) - d.begin());
    // Rule 3: the last still stretch in the upper half of the cast ends the soak.
    const std::size_t w = static_cast<std::size_t>(kSoakSamples);
    std::size_t start = 0;
    for (std::size_t i = k; i >= w; --i) {
        if (d[i] <= 0.5 * d[k]) {
            const auto [lo, hi] =
                std::minmax_element(d.begin() + static_cast<std::ptrdiff_t>(i - w),
                                    d.begin() + static_cast<std::ptrdiff_t>(i + 1));
            if (*hi - *lo < kSoakSpan_m) {
                start = i;
                break;
            }
        }
    }
    for (std::size_t i = start; i <= k; ++i) {
        if (keep.empty() || d[i] > d[keep.back()]) keep.push_back(i);
    }
    if (stats) {
        stats->up_cast += d.size() - 1 - k;
        stats->soak += start;
        stats->thinned += k + 1 - start - keep.size();
    }
    return keep;
}

}  // namespace pitmap::proc::svp
