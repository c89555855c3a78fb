// SPDX-License-Identifier: MIT
// 83P record decoder/encoder. Spec: shared/specs/imagenex_deltat.md §1.2-1.4, §2.3, §4.
#include "common/protocol/deltat/record83p.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>

#include "common/gps_time.hpp"

namespace pitmap::protocol::deltat {
namespace {

constexpr std::size_t kOffsetVersion = 3;
constexpr std::size_t kOffsetLength = 4;
constexpr std::size_t kOffsetReserved6 = 6;
constexpr std::size_t kOffsetDate = 8;
constexpr std::size_t kOffsetNumBeams = 70;
constexpr std::size_t kOffsetFloatBlock = 100;
constexpr std::size_t kOffsetIntensityFlag = 117;

constexpr std::array<std::size_t, kNumFloatFields> kFloatOffsets = {
    100, 104, 108, 128, 133, 138, 142, 146, 151};

constexpr std::array<std::string_view, 12> kMonths = {
    "JAN", "FEB", "MAR", "APR", "MAY", "JUN", "JUL", "AUG", "SEP", "OCT", "NOV", "DEC"};

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

bool IsDigit(char c) {
    return c >= '0' && c <= '9';
}
// Blank positions of the navigation strings: space, MB-System's underscore, or NUL (§4.10).
bool IsPad(char c) {
    return c == ' ' || c == '_' || c == '\0';
}
char ToUpper(char c) {
    return (c >= 'a' && c <= 'z') ? static_cast<char>(c - 'a' + 'A') : c;
}

// Digits at text[pos, pos+n); with `allow_leading_pad`, leading pads count as zeros (space-
// padded minutes, §1.4). Returns -1 if malformed.
int ParseDigits(std::string_view text, std::size_t pos, std::size_t n, bool allow_leading_pad) {
    if (pos + n > text.size()) return -1;
    int value = 0;
    bool seen_digit = false;
    for (std::size_t i = pos; i < pos + n; ++i) {
        const char c = text[i];
        if (IsDigit(c)) {
            value = value * 10 + (c - '0');
            seen_digit = true;
        } else if (allow_leading_pad && !seen_digit && IsPad(c)) {
            continue;
        } else {
            return -1;
        }
    }
    return value;
}

// Shared by latitude and longitude: `deg_digits` = 2 or 3, text is 14 characters.
//   lat: [0] pad, [1-2] deg, [3] sep, [4-5] min, [6] sep, [7-11] frac, [12] pad, [13] N/S
//   lon: [0-2] deg, [3] sep, [4-5] min, [6] sep, [7-11] frac, [12] pad, [13] E/W
double ParseNavText(std::string_view text, bool latitude) {
    if (text.size() < 14) return kNaN;
    bool all_blank_or_zero = true;
    for (char c : text.substr(0, 14)) {
        if (!IsPad(c) && c != '0' && c != '.') all_blank_or_zero = false;
    }
    if (all_blank_or_zero) return kNaN;
    int deg = 0;
    if (latitude) {
        if (!IsPad(text[0]) && text[0] != '0') return kNaN;
        deg = ParseDigits(text, 1, 2, true);
    } else {
        deg = ParseDigits(text, 0, 3, true);
    }
    const bool sep_ok = (text[3] == '.' || IsPad(text[3])) && (text[6] == '.' || IsPad(text[6]));
    const int minutes = ParseDigits(text, 4, 2, true);
    const int frac = ParseDigits(text, 7, 5, false);
    const char hemi = ToUpper(text[13]);
    const char positive = latitude ? 'N' : 'E';
    const char negative = latitude ? 'S' : 'W';
    if (!sep_ok || deg < 0 || minutes < 0 || frac < 0 || !IsPad(text[12]) ||
        (hemi != positive && hemi != negative)) {
        return kNaN;
    }
    const int max_deg = latitude ? 90 : 180;
    if (minutes >= 60 || deg > max_deg) return kNaN;
    if (deg == 0 && minutes == 0 && frac == 0) return kNaN;  // "all zero": no GNSS input
    const double value = deg + (minutes + frac / 100000.0) / 60.0;
    if (value > max_deg) return kNaN;
    return hemi == negative ? -value : value;
}

template <std::size_t N>
std::string_view View(const std::array<char, N>& a) {
    return std::string_view(a.data(), N);
}

template <std::size_t N>
void CopyText(ByteReader& r, std::array<char, N>& dst) {
    const ByteSpan src = r.Bytes(N);
    if (src.size() == N) {
        for (std::size_t i = 0; i < N; ++i) dst[i] = static_cast<char>(src[i]);
    } else {
        dst.fill('\0');
    }
}

template <std::size_t N>
void WriteText(ByteWriter& w, const std::array<char, N>& text) {
    for (char c : text) w.U8(static_cast<std::uint8_t>(c));
}

// A swapped float takes its exponent from a mantissa byte: for values with few significant
// bits it lands far below any physical magnitude. |v| < 1e-6 (but != 0) is therefore treated
// as the wrong byte order, in addition to the windows of §4.5.
constexpr float kTinyFloat = 1e-6f;

bool PlausibleFloat(FloatField f, float v) {
    if (!std::isfinite(v)) return false;
    if (v != 0.0f && std::fabs(v) < kTinyFloat) return false;
    switch (f) {
        case FloatField::kOffsetX:
        case FloatField::kOffsetY:
        case FloatField::kOffsetZ:
        case FloatField::kHeave:
            return std::fabs(v) < 100.0f;
        case FloatField::kAltitude:
            return v >= 0.0f && v <= 1000.0f;
        case FloatField::kExternalPitch:
        case FloatField::kExternalRoll:
        case FloatField::kScanAngle:
            return std::fabs(v) <= 90.0f;
        case FloatField::kExternalHeading:
            return v >= 0.0f && v <= 360.0f;
        case FloatField::kCount:
            break;
    }
    return false;
}

// Order used when both are plausible and the stream has no memory yet: big-endian as the
// vendor table says, except where open readers observed little-endian (altitude [C], scan
// angle [1]); spec §1.1 / §1.2. [U] until checked on the real unit.
FloatOrder DefaultOrder(FloatField f) {
    return (f == FloatField::kAltitude || f == FloatField::kScanAngle) ? FloatOrder::kLittle
                                                                       : FloatOrder::kBig;
}

float ReadFloat(ByteSpan rec, FloatField f, FloatOrderMemory& memory, Ping83P& out) {
    const auto idx = static_cast<std::size_t>(f);
    ByteReader r(rec);
    r.Seek(kFloatOffsets[idx]);
    const ByteSpan raw = r.Bytes(4);
    if (raw.size() != 4 || (raw[0] | raw[1] | raw[2] | raw[3]) == 0) {
        out.float_order[idx] = FloatOrder::kUnknown;
        return 0.0f;  // exact zero is the same in both orders: no decision, no memory update
    }
    ByteReader rb(raw);
    const float be = rb.F32Be();
    ByteReader rl(raw);
    const float le = rl.F32Le();
    const bool be_ok = PlausibleFloat(f, be);
    const bool le_ok = PlausibleFloat(f, le);
    const FloatOrder remembered = memory.Get(f);
    const FloatOrder preferred = remembered != FloatOrder::kUnknown ? remembered : DefaultOrder(f);
    FloatOrder chosen = preferred;
    if (be_ok != le_ok) {
        chosen = be_ok ? FloatOrder::kBig : FloatOrder::kLittle;
        memory.Set(f, chosen);
    } else if (!be_ok) {
        out.float_implausible_mask =
            static_cast<std::uint16_t>(out.float_implausible_mask | (1u << idx));
    }
    out.float_order[idx] = chosen;
    return chosen == FloatOrder::kBig ? be : le;
}

void DecodeAttitude(std::uint16_t raw, bool heading, bool& valid, double& deg) {
    valid = (raw & 0x8000u) != 0;
    const int v = raw & 0x7FFF;
    deg = valid ? (heading ? v / 10.0 : (v - 900) / 10.0) : kNaN;
}

// Rounds v*scale+offset to the nearest integer in [0, max]; NaN -> 0.
std::uint32_t Quantize(double v, double scale, double offset, std::uint32_t max) {
    if (!std::isfinite(v)) return 0;
    const double q = std::round(v * scale + offset);
    if (q <= 0.0) return 0;
    if (q >= static_cast<double>(max)) return max;
    return static_cast<std::uint32_t>(q);
}

std::uint16_t EncodeAttitude(bool valid, double deg, bool heading) {
    if (!valid) return 0;
    const auto v = Quantize(deg, 10.0, heading ? 0.0 : 900.0, 0x7FFF);
    return static_cast<std::uint16_t>(0x8000u | v);
}

void WriteFloat(ByteWriter& w, float v, FloatOrder order) {
    if (order == FloatOrder::kLittle) {
        w.F32Le(v);
    } else {
        w.F32Be(v);
    }
}

DecodeError Error(DecodeErrorKind kind, std::size_t offset, std::string_view message) {
    return DecodeError{kind, offset, message};
}

void FormatNav(std::array<char, 14>& text, double deg, bool latitude) {
    if (!std::isfinite(deg) || std::fabs(deg) > (latitude ? 90.0 : 180.0)) {
        text.fill(' ');
        return;
    }
    // Units of 1e-5 minute, rounded once so that minutes never print as 60.
    const auto total = static_cast<std::int64_t>(std::llround(std::fabs(deg) * 60.0 * 1e5));
    const std::int64_t d = total / 6'000'000;
    const std::int64_t rem = total % 6'000'000;
    const std::int64_t m = rem / 100'000;
    const std::int64_t f = rem % 100'000;
    const char hemi = latitude ? (deg < 0 ? 'S' : 'N') : (deg < 0 ? 'W' : 'E');
    char buf[32];
    if (latitude) {
        std::snprintf(buf,
                      sizeof buf,
                      " %02d.%02d.%05d %c",
                      static_cast<int>(d),
                      static_cast<int>(m),
                      static_cast<int>(f),
                      hemi);
    } else {
        std::snprintf(buf,
                      sizeof buf,
                      "%03d.%02d.%05d %c",
                      static_cast<int>(d),
                      static_cast<int>(m),
                      static_cast<int>(f),
                      hemi);
    }
    std::memcpy(text.data(), buf, text.size());
}

}  // namespace

std::optional<std::int64_t> ParseHeaderClock(std::string_view date,
                                             std::string_view time,
                                             std::string_view fraction) {
    if (date.size() < 11 || time.size() < 8 || fraction.size() < 3) return std::nullopt;
    UtcCalendar c;
    c.day = ParseDigits(date, 0, 2, false);
    c.year = ParseDigits(date, 7, 4, false);
    c.month = 0;
    const char mon[3] = {ToUpper(date[3]), ToUpper(date[4]), ToUpper(date[5])};
    for (std::size_t i = 0; i < kMonths.size(); ++i) {
        if (std::string_view(mon, 3) == kMonths[i]) c.month = static_cast<int>(i) + 1;
    }
    c.hour = ParseDigits(time, 0, 2, false);
    c.minute = ParseDigits(time, 3, 2, false);
    c.second = ParseDigits(time, 6, 2, false);
    if (date[2] != '-' || date[6] != '-' || time[2] != ':' || time[5] != ':' ||
        fraction[0] != '.' || c.day < 0 || c.year < 0 || c.hour < 0 || c.minute < 0 ||
        c.second < 0) {
        return std::nullopt;
    }
    // ".hh" or ".mmm": the digits after the dot up to NUL/end are a decimal fraction.
    std::size_t n = 1;
    while (n < fraction.size() && IsDigit(fraction[n])) ++n;
    const std::size_t digits = n - 1;
    if (digits < 2 || digits > 3 || (n < fraction.size() && fraction[n] != '\0')) {
        return std::nullopt;
    }
    const int frac = ParseDigits(fraction, 1, digits, false);
    c.microsecond = digits == 2 ? frac * 10'000 : frac * 1'000;
    return UnixFromUtcCalendar(c);
}

double ParseLatitudeText(std::string_view text14) {
    return ParseNavText(text14, true);
}
double ParseLongitudeText(std::string_view text14) {
    return ParseNavText(text14, false);
}

void SetHeaderTime(Ping83P& ping, std::int64_t utime_unix) {
    const UtcCalendar c = UtcCalendarFromUnix(utime_unix);
    ping.date_text.fill('\0');
    ping.time_text.fill('\0');
    ping.hundredths_text.fill('\0');
    ping.milliseconds_text.fill('\0');
    ping.header_time_valid = false;
    ping.utime_sonar_header = 0;
    if (c.year < 0 || c.year > 9999) return;
    char buf[32];
    std::snprintf(buf,
                  sizeof buf,
                  "%02d-%s-%04d",
                  c.day,
                  kMonths[static_cast<std::size_t>(c.month - 1)].data(),
                  c.year);
    std::memcpy(ping.date_text.data(), buf, 11);
    std::snprintf(buf, sizeof buf, "%02d:%02d:%02d", c.hour, c.minute, c.second);
    std::memcpy(ping.time_text.data(), buf, 8);
    std::snprintf(buf, sizeof buf, ".%02d", c.microsecond / 10'000);
    std::memcpy(ping.hundredths_text.data(), buf, 3);
    if (ping.is_v110()) {
        std::snprintf(buf, sizeof buf, ".%03d", c.microsecond / 1'000);
        std::memcpy(ping.milliseconds_text.data(), buf, 4);
    }
    const auto parsed = ParseHeaderClock(
        View(ping.date_text),
        View(ping.time_text),
        ping.is_v110() ? View(ping.milliseconds_text) : View(ping.hundredths_text));
    ping.header_time_valid = parsed.has_value();
    ping.utime_sonar_header = parsed.value_or(0);
}

void SetHeaderLatitude(Ping83P& ping, double latitude_deg) {
    FormatNav(ping.latitude_text, latitude_deg, true);
    ping.latitude_deg = ParseLatitudeText(View(ping.latitude_text));
}

void SetHeaderLongitude(Ping83P& ping, double longitude_deg) {
    FormatNav(ping.longitude_text, longitude_deg, false);
    ping.longitude_deg = ParseLongitudeText(View(ping.longitude_text));
}

std::variant<Layout83P, DecodeError> ValidateHeader83P(ByteSpan prefix) {
    ByteReader r(prefix);
    const std::uint8_t m0 = r.U8();
    const std::uint8_t m1 = r.U8();
    const std::uint8_t m2 = r.U8();
    if (!r.ok()) return Error(DecodeErrorKind::kTruncated, prefix.size(), "shorter than marker");
    if (m0 != kMarker0 || m1 != kMarker1 || m2 != kMarker2) {
        if (m0 == kMarker0 && m1 == kMarker1 && (m2 == 'B' || m2 == 'M')) {
            return Error(DecodeErrorKind::kUnsupported, 0, "83B/83M record is not decoded");
        }
        return Error(DecodeErrorKind::kBadMarker, 0, "no 83P marker");
    }
    Layout83P layout;
    layout.format_version = r.U8();
    layout.total_bytes = r.U16Be();
    if (!r.ok()) return Error(DecodeErrorKind::kTruncated, prefix.size(), "header truncated");
    // Reject an impossible N as soon as it is seen (no waiting for the rest of the header).
    if (layout.total_bytes < kHeaderBytes || layout.total_bytes > kMaxRecordBytes) {
        return Error(DecodeErrorKind::kBadLength, kOffsetLength, "N outside 256..2176");
    }
    const std::uint8_t c0 = r.U8();
    const std::uint8_t c1 = r.U8();
    if (!r.ok()) return Error(DecodeErrorKind::kTruncated, prefix.size(), "header truncated");
    if (layout.total_bytes == kHeaderBytes && c0 == '#' && c1 == '#') {
        layout.comment = true;
        return layout;
    }
    if (prefix.size() < kMinBytesToValidate) {
        return Error(DecodeErrorKind::kTruncated, prefix.size(), "header truncated");
    }
    r.Seek(kOffsetNumBeams);
    layout.num_beams = r.U16Be();
    if (layout.num_beams < 1 || layout.num_beams > kMaxBeams) {
        return Error(DecodeErrorKind::kBadBeamCount, kOffsetNumBeams, "B outside 1..480");
    }
    const bool v110 = layout.format_version >= kVersion110;
    const bool flag = v110 && prefix[kOffsetIntensityFlag] == 1;
    const std::size_t ranges_only = kHeaderBytes + 2u * layout.num_beams;
    const std::size_t with_intensity = kHeaderBytes + 4u * layout.num_beams;
    if (flag && layout.total_bytes == with_intensity) {
        layout.intensity = true;
    } else if (layout.total_bytes == ranges_only) {
        layout.intensity_flag_ignored = flag;
    } else {
        return Error(
            DecodeErrorKind::kLengthMismatch, kOffsetLength, "N inconsistent with B and byte 117");
    }
    return layout;
}

std::variant<RecordKind, DecodeError> DecodeRecord83PInto(ByteSpan record,
                                                          FloatOrderMemory& memory,
                                                          Ping83P& out) {
    const auto validated = ValidateHeader83P(record);
    if (const auto* e = std::get_if<DecodeError>(&validated)) return *e;
    const Layout83P& layout = std::get<Layout83P>(validated);
    if (record.size() < layout.total_bytes) {
        return Error(DecodeErrorKind::kTruncated, record.size(), "fewer bytes than N");
    }
    if (record.size() > layout.total_bytes) {
        return Error(DecodeErrorKind::kTrailingBytes, layout.total_bytes, "more bytes than N");
    }
    if (layout.comment) return RecordKind::kComment;

    // Reset every field but keep the vectors' capacity (decode in place, no allocation).
    std::vector<std::uint16_t> ranges = std::move(out.range_counts);
    std::vector<std::uint16_t> intensities = std::move(out.intensities);
    out = Ping83P{};
    out.range_counts = std::move(ranges);
    out.intensities = std::move(intensities);

    ByteReader r(record);
    r.Seek(kOffsetVersion);
    out.format_version = r.U8();
    out.total_bytes = r.U16Be();
    r.Seek(kOffsetDate);
    CopyText(r, out.date_text);
    CopyText(r, out.time_text);
    CopyText(r, out.hundredths_text);
    CopyText(r, out.latitude_text);
    CopyText(r, out.longitude_text);
    out.speed_over_ground_knots = r.U8() / 10.0;
    out.course_over_ground_deg = r.U16Be() / 10.0;
    DecodeAttitude(r.U16Be(), false, out.internal_pitch_valid, out.internal_pitch_deg);
    DecodeAttitude(r.U16Be(), false, out.internal_roll_valid, out.internal_roll_deg);
    DecodeAttitude(r.U16Be(), true, out.internal_heading_valid, out.internal_heading_deg);
    r.U16Be();  // B, validated above
    out.samples_per_beam = r.U16Be();
    out.sector_size_deg = r.U16Be();
    out.start_angle_cdeg = static_cast<std::int32_t>(r.U16Be()) - 18000;
    out.angle_increment_cdeg = r.U8();
    out.acoustic_range_m = r.U16Be();
    out.frequency_khz = r.U16Be();
    const std::uint16_t sv = r.U16Be();
    out.sound_velocity_flag = (sv & 0x8000u) != 0;
    out.sound_velocity_header_mps = out.sound_velocity_flag ? (sv & 0x7FFF) / 10.0 : 0.0;
    out.sound_velocity_valid = out.sound_velocity_flag &&
                               out.sound_velocity_header_mps >= kMinPlausibleSoundVelocityMps &&
                               out.sound_velocity_header_mps <= kMaxPlausibleSoundVelocityMps;
    out.sound_velocity_mps =
        out.sound_velocity_valid ? out.sound_velocity_header_mps : kDefaultSoundVelocityMps;
    out.range_resolution_mm = r.U16Be();
    out.pulse_length_us = r.U16Be();
    const std::uint16_t tilt = r.U16Be();
    // §4.8: raw 0 -> 0 deg (MB-System); bit15 -> 837-style tenths [U]; else integer + 180.
    out.profile_tilt_837_style = (tilt & 0x8000u) != 0;
    if (out.profile_tilt_837_style) {
        out.profile_tilt_deg = (tilt & 0x7FFF) / 10.0 - 180.0;
    } else {
        out.profile_tilt_deg = tilt == 0 ? 0.0 : static_cast<double>(tilt) - 180.0;
    }
    out.repetition_rate_ms = r.U16Be();
    out.ping_number = r.U32Be();

    if (out.is_v110()) {
        out.sonar_offset_m[0] = ReadFloat(record, FloatField::kOffsetX, memory, out);
        out.sonar_offset_m[1] = ReadFloat(record, FloatField::kOffsetY, memory, out);
        out.sonar_offset_m[2] = ReadFloat(record, FloatField::kOffsetZ, memory, out);
        r.Seek(112);
        CopyText(r, out.milliseconds_text);
        out.intensity_flag_raw = r.U8();
        out.ping_latency_us = static_cast<std::int32_t>(r.U16Be()) * 100;
        out.data_latency_us = static_cast<std::int32_t>(r.U16Be()) * 100;
        out.sample_rate = r.U8();
        out.option_flags = r.U8();
        r.U8();  // 124 reserved
        out.pings_averaged = r.U8();
        out.center_ping_offset_us = static_cast<std::int32_t>(r.U16Be()) * 100;
        out.heave_m = ReadFloat(record, FloatField::kHeave, memory, out);
        r.Seek(132);
        out.user_byte = r.U8();
        out.altitude_m = ReadFloat(record, FloatField::kAltitude, memory, out);
        r.Seek(137);
        out.external_sensor_flags = r.U8();
        out.external_pitch_deg = ReadFloat(record, FloatField::kExternalPitch, memory, out);
        out.external_roll_deg = ReadFloat(record, FloatField::kExternalRoll, memory, out);
        out.external_heading_deg = ReadFloat(record, FloatField::kExternalHeading, memory, out);
        r.Seek(150);
        out.transmit_scan_flag = r.U8();
        out.transmit_scan_angle_deg = ReadFloat(record, FloatField::kScanAngle, memory, out);
    }
    out.intensity_included = layout.intensity;
    out.intensity_flag_ignored = layout.intensity_flag_ignored;

    // §1.4 time: ms (v1.10) over hundredths; v1.10 falls back to hundredths if ms is bad.
    std::optional<std::int64_t> clock;
    if (out.is_v110()) {
        clock =
            ParseHeaderClock(View(out.date_text), View(out.time_text), View(out.milliseconds_text));
    }
    if (!clock) {
        clock =
            ParseHeaderClock(View(out.date_text), View(out.time_text), View(out.hundredths_text));
    }
    out.header_time_valid = clock.has_value();
    out.utime_sonar_header = clock.value_or(0);
    out.latitude_deg = ParseLatitudeText(View(out.latitude_text));
    out.longitude_deg = ParseLongitudeText(View(out.longitude_text));

    const std::size_t num_beams = layout.num_beams;
    r.Seek(kHeaderBytes);
    ByteReader ranges_reader(r.Bytes(2 * num_beams));
    out.range_counts.resize(num_beams);
    for (std::size_t i = 0; i < num_beams; ++i) out.range_counts[i] = ranges_reader.U16Be();
    if (layout.intensity) {
        ByteReader amp_reader(r.Bytes(2 * num_beams));
        out.intensities.resize(num_beams);
        for (std::size_t i = 0; i < num_beams; ++i) out.intensities[i] = amp_reader.U16Be();
    } else {
        out.intensities.clear();
    }
    if (!r.ok()) return Error(DecodeErrorKind::kTruncated, record.size(), "beam block short");
    return RecordKind::kPing;
}

Decoded83P DecodeRecord83P(ByteSpan record, FloatOrderMemory& memory) {
    Ping83P ping;
    auto result = DecodeRecord83PInto(record, memory, ping);
    if (const auto* e = std::get_if<DecodeError>(&result)) return *e;
    if (std::get<RecordKind>(result) == RecordKind::kComment) {
        Comment83P comment;
        comment.format_version = record[kOffsetVersion];
        for (std::size_t i = 0; i < comment.text.size(); ++i) {
            comment.text[i] = static_cast<char>(record[kOffsetDate + i]);
        }
        return comment;
    }
    return ping;
}

Decoded83P DecodeRecord83P(ByteSpan record) {
    FloatOrderMemory memory;
    return DecodeRecord83P(record, memory);
}

bool EncodeRecord83P(const Ping83P& ping,
                     const EncodeOptions& options,
                     std::vector<std::uint8_t>& out) {
    const std::size_t num_beams = ping.range_counts.size();
    if (num_beams < 1 || num_beams > kMaxBeams) return false;
    const bool v110 = ping.is_v110();
    const bool want_intensity = v110 && ping.intensity_included;
    if (want_intensity && ping.intensities.size() != num_beams) return false;
    const bool write_intensity = want_intensity && !options.mbsystem_short_length;
    const std::size_t total = kHeaderBytes + (write_intensity ? 4 : 2) * num_beams;

    out.reserve(out.size() + total);
    const std::size_t start = out.size();
    ByteWriter w(out);
    w.U8(kMarker0);
    w.U8(kMarker1);
    w.U8(kMarker2);
    w.U8(ping.format_version);
    w.U16Be(static_cast<std::uint16_t>(total));
    w.U16Be(0);
    WriteText(w, ping.date_text);
    WriteText(w, ping.time_text);
    WriteText(w, ping.hundredths_text);
    WriteText(w, ping.latitude_text);
    WriteText(w, ping.longitude_text);
    w.U8(static_cast<std::uint8_t>(Quantize(ping.speed_over_ground_knots, 10.0, 0.0, 0xFF)));
    w.U16Be(static_cast<std::uint16_t>(Quantize(ping.course_over_ground_deg, 10.0, 0.0, 0xFFFF)));
    w.U16Be(EncodeAttitude(ping.internal_pitch_valid, ping.internal_pitch_deg, false));
    w.U16Be(EncodeAttitude(ping.internal_roll_valid, ping.internal_roll_deg, false));
    w.U16Be(EncodeAttitude(ping.internal_heading_valid, ping.internal_heading_deg, true));
    w.U16Be(static_cast<std::uint16_t>(num_beams));
    w.U16Be(ping.samples_per_beam);
    w.U16Be(ping.sector_size_deg);
    w.U16Be(static_cast<std::uint16_t>(std::clamp(ping.start_angle_cdeg + 18000, 0, 0xFFFF)));
    w.U8(ping.angle_increment_cdeg);
    w.U16Be(ping.acoustic_range_m);
    w.U16Be(ping.frequency_khz);
    w.U16Be(ping.sound_velocity_flag
                ? static_cast<std::uint16_t>(
                      0x8000u | Quantize(ping.sound_velocity_header_mps, 10.0, 0.0, 0x7FFF))
                : std::uint16_t{0});
    w.U16Be(ping.range_resolution_mm);
    w.U16Be(ping.pulse_length_us);
    w.U16Be(ping.profile_tilt_837_style
                ? static_cast<std::uint16_t>(0x8000u |
                                             Quantize(ping.profile_tilt_deg, 10.0, 1800.0, 0x7FFF))
                : static_cast<std::uint16_t>(Quantize(ping.profile_tilt_deg, 1.0, 180.0, 0x7FFF)));
    w.U16Be(ping.repetition_rate_ms);
    w.U32Be(ping.ping_number);
    w.Zeros(3);
    if (v110) {
        const FloatOrder order = options.float_order;
        for (float v : ping.sonar_offset_m) WriteFloat(w, v, order);
        WriteText(w, ping.milliseconds_text);
        w.U8(want_intensity ? 1 : 0);
        w.U16Be(static_cast<std::uint16_t>(Quantize(ping.ping_latency_us, 0.01, 0.0, 0xFFFF)));
        w.U16Be(static_cast<std::uint16_t>(Quantize(ping.data_latency_us, 0.01, 0.0, 0xFFFF)));
        w.U8(ping.sample_rate);
        w.U8(ping.option_flags);
        w.U8(0);
        w.U8(ping.pings_averaged);
        w.U16Be(
            static_cast<std::uint16_t>(Quantize(ping.center_ping_offset_us, 0.01, 0.0, 0xFFFF)));
        WriteFloat(w, ping.heave_m, order);
        w.U8(ping.user_byte);
        WriteFloat(w, ping.altitude_m, order);
        w.U8(ping.external_sensor_flags);
        WriteFloat(w, ping.external_pitch_deg, order);
        WriteFloat(w, ping.external_roll_deg, order);
        WriteFloat(w, ping.external_heading_deg, order);
        w.U8(ping.transmit_scan_flag);
        WriteFloat(w, ping.transmit_scan_angle_deg, order);
        w.Zeros(kHeaderBytes - 155);
    } else {
        w.Zeros(kHeaderBytes - kOffsetFloatBlock);
    }
    for (std::uint16_t v : ping.range_counts) w.U16Be(v);
    if (write_intensity) {
        for (std::uint16_t v : ping.intensities) w.U16Be(v);
    }
    return out.size() - start == total;
}

std::vector<std::uint8_t> EncodeRecord83P(const Ping83P& ping, const EncodeOptions& options) {
    std::vector<std::uint8_t> out;
    if (!EncodeRecord83P(ping, options, out)) out.clear();
    return out;
}

std::vector<std::uint8_t> EncodeComment83P(std::string_view text, std::uint8_t format_version) {
    std::vector<std::uint8_t> out;
    out.reserve(kHeaderBytes);
    ByteWriter w(out);
    w.U8(kMarker0);
    w.U8(kMarker1);
    w.U8(kMarker2);
    w.U8(format_version);
    w.U16Be(static_cast<std::uint16_t>(kHeaderBytes));
    w.U8('#');
    w.U8('#');
    // Keep at least one NUL at the end of the text area.
    w.FixedString(text.substr(0, std::min<std::size_t>(text.size(), kHeaderBytes - 9)),
                  kHeaderBytes - kOffsetDate);
    static_assert(kOffsetReserved6 + 2 == kOffsetDate);
    return out;
}

}  // namespace pitmap::protocol::deltat
