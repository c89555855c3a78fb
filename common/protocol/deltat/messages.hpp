// SPDX-License-Identifier: MIT
// Imagenex Delta T (model 837): decoded message structs and the shared error type.
//
// Reference: pitmap spec "Imagenex DeltaT (model 837) — data formats and network protocols"
// (shared/specs/imagenex_deltat.md): §1.2 83P header, §1.3 beam block, §1.4 field decoding,
// §1.5 beam geometry, §4 reader quirks. Formats 83P v1.00 (version byte 0) and v1.10 (>= 10),
// as defined by the Imagenex 83P document of 16 Mar 2010 (transcribed in MB-System).
//
// Plain structs, SI-ish units in the field names, no LCM. Raw range counts are kept so the
// shore side can apply either slant-range convention (§1.5 [U]).
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string_view>
#include <vector>

namespace pitmap::protocol::deltat {

// §1.1-1.3 sizes.
inline constexpr std::size_t kHeaderBytes = 256;
inline constexpr std::size_t kMaxBeams = 480;
inline constexpr std::size_t kMaxRecordBytes = kHeaderBytes + 4 * kMaxBeams;  // 2176
// Bytes needed to validate a header's length fields (N at 4-5, B at 70-71, flag at 117).
inline constexpr std::size_t kMinBytesToValidate = 118;
inline constexpr std::uint8_t kMarker0 = '8';
inline constexpr std::uint8_t kMarker1 = '3';
inline constexpr std::uint8_t kMarker2 = 'P';
inline constexpr std::uint8_t kVersion100 = 0;
inline constexpr std::uint8_t kVersion110 = 10;

// What went wrong in a decoder. `offset` is the byte offset inside the record or frame.
enum class DecodeErrorKind : std::uint8_t {
    kTruncated = 0,   // fewer bytes than the header (or N) requires
    kTrailingBytes,   // more bytes than N (datagram) or than the fixed frame size
    kBadMarker,       // not `83P` / `EC` / 0xFE 0x44 / `I?X`
    kUnsupported,     // a known but unsupported record (83B, 83M): log verbatim, skip
    kBadLength,       // N < 256 or N > 2176
    kBadBeamCount,    // B outside 1..480
    kLengthMismatch,  // N matches neither 256+2B nor 256+4B as allowed by byte 117
    kBadTerminator,   // fixed-size frame without its terminator byte
    kBadValue,        // a coded field outside its table (EC range code, sector, ...)
    kCount
};

constexpr std::string_view ToString(DecodeErrorKind k) {
    switch (k) {
        case DecodeErrorKind::kTruncated:
            return "truncated";
        case DecodeErrorKind::kTrailingBytes:
            return "trailing_bytes";
        case DecodeErrorKind::kBadMarker:
            return "bad_marker";
        case DecodeErrorKind::kUnsupported:
            return "unsupported";
        case DecodeErrorKind::kBadLength:
            return "bad_length";
        case DecodeErrorKind::kBadBeamCount:
            return "bad_beam_count";
        case DecodeErrorKind::kLengthMismatch:
            return "length_mismatch";
        case DecodeErrorKind::kBadTerminator:
            return "bad_terminator";
        case DecodeErrorKind::kBadValue:
            return "bad_value";
        case DecodeErrorKind::kCount:
            break;
    }
    return "unknown";
}

struct DecodeError {
    DecodeErrorKind kind = DecodeErrorKind::kTruncated;
    std::size_t offset = 0;
    std::string_view message;  // static text, never allocated
};

// Byte order chosen for one IEEE float field of a v1.10 header (§1.1, §4.5).
enum class FloatOrder : std::uint8_t {
    kUnknown = 0,  // not decided (field was 0, or the record is v1.00)
    kBig,
    kLittle,
};

// The float fields of the v1.10 header, in offset order; index into the arrays below.
enum class FloatField : std::uint8_t {
    kOffsetX = 0,      // 100
    kOffsetY,          // 104
    kOffsetZ,          // 108
    kHeave,            // 128
    kAltitude,         // 133
    kExternalPitch,    // 138
    kExternalRoll,     // 142
    kExternalHeading,  // 146
    kScanAngle,        // 151
    kCount
};
inline constexpr std::size_t kNumFloatFields = static_cast<std::size_t>(FloatField::kCount);

// Per-stream memory of the float byte order chosen for each field (§4.5). The caller keeps
// one per UDP source or file and passes it to every decode of that stream. Not thread safe.
struct FloatOrderMemory {
    std::array<FloatOrder, kNumFloatFields> order{};
    FloatOrder Get(FloatField f) const { return order[static_cast<std::size_t>(f)]; }
    void Set(FloatField f, FloatOrder o) { order[static_cast<std::size_t>(f)] = o; }
};

// Byte 123 option flags.
inline constexpr std::uint8_t kOptionRollCorrected = 0x01;
inline constexpr std::uint8_t kOptionRayBendingCorrected = 0x02;
inline constexpr std::uint8_t kOptionOverlapped = 0x04;
// Byte 137 external sensor flags.
inline constexpr std::uint8_t kExternalHeadingValid = 0x01;
inline constexpr std::uint8_t kExternalRollValid = 0x02;
inline constexpr std::uint8_t kExternalPitchValid = 0x04;
inline constexpr std::uint8_t kExternalHeaveValid = 0x08;

// Sound velocity window outside which the header value is not trusted (§1.4, MB-System).
inline constexpr double kMinPlausibleSoundVelocityMps = 1300.0;
inline constexpr double kMaxPlausibleSoundVelocityMps = 1700.0;
inline constexpr double kDefaultSoundVelocityMps = 1500.0;

// One 83P ping record (§1.2-1.4). Text fields are kept verbatim (fixed arrays, NUL padded):
// the encoder writes them as they are, the decoder parses the numeric values from them. Use
// SetHeaderTime / SetHeaderLatitude / SetHeaderLongitude to fill both consistently.
// Numeric fields are in physical units; the encoder quantises them to the wire resolution
// (round to nearest), so decode(encode(p)) reproduces p exactly once p came from a decode.
struct Ping83P {
    std::uint8_t format_version = kVersion110;  // byte 3: 0 = v1.00, >= 10 = v1.10 layout
    std::uint16_t total_bytes = 0;              // N as read (decoder); ignored by the encoder

    // Clock of the topside PC (not UTC-disciplined, §1.4), bytes 8-32 and 112-116.
    std::array<char, 12> date_text{};         // "DD-MMM-YYYY"
    std::array<char, 9> time_text{};          // "HH:MM:SS"
    std::array<char, 4> hundredths_text{};    // ".hh"
    std::array<char, 5> milliseconds_text{};  // ".mmm" (v1.10)
    bool header_time_valid = false;           // false: date/time text not parsable
    std::int64_t utime_sonar_header = 0;      // Unix microseconds as if UTC; 0 if not valid

    // Navigation strings from the topside software, bytes 33-60 (§1.4).
    std::array<char, 14> latitude_text{};
    std::array<char, 14> longitude_text{};
    double latitude_deg = std::numeric_limits<double>::quiet_NaN();   // NaN: blank/zero/bad
    double longitude_deg = std::numeric_limits<double>::quiet_NaN();  // NaN: blank/zero/bad
    double speed_over_ground_knots = 0.0;                             // byte 61, 0.1 kn
    double course_over_ground_deg = 0.0;                              // bytes 62-63, 0.1 deg

    // Internal attitude sensor, bytes 64-69: bit15 = valid. Values are NaN when not valid.
    bool internal_pitch_valid = false;
    bool internal_roll_valid = false;
    bool internal_heading_valid = false;
    double internal_pitch_deg = std::numeric_limits<double>::quiet_NaN();
    double internal_roll_deg = std::numeric_limits<double>::quiet_NaN();
    double internal_heading_deg = std::numeric_limits<double>::quiet_NaN();

    // Sonar settings, bytes 70-96. B (bytes 70-71) is range_counts.size().
    std::uint16_t samples_per_beam = 0;
    std::uint16_t sector_size_deg = 0;
    std::int32_t start_angle_cdeg = 0;      // beam 0 angle, 0.01 deg, starboard positive (§1.5)
    std::uint8_t angle_increment_cdeg = 0;  // 0.01 deg per beam
    std::uint16_t acoustic_range_m = 0;
    std::uint16_t frequency_khz = 0;
    bool sound_velocity_flag = false;        // V bit of bytes 83-84
    double sound_velocity_header_mps = 0.0;  // (bits 0-14)/10 as written; 0 when V clear
    double sound_velocity_mps = kDefaultSoundVelocityMps;  // effective value (§4.7)
    bool sound_velocity_valid = false;                     // V set and inside 1300..1700 m/s
    std::uint16_t range_resolution_mm = 0;                 // millimetres per range count
    std::uint16_t pulse_length_us = 0;    // bytes 87-88 as read (vendor: reserved) [U]
    double profile_tilt_deg = 0.0;        // fore/aft fan tilt tau (§1.4, §4.8)
    bool profile_tilt_837_style = false;  // bytes 89-90 had bit15 set: ((v&0x7FFF)/10)-180
    std::uint16_t repetition_rate_ms = 0;
    std::uint32_t ping_number = 0;

    // v1.10 only (bytes 100-154); zero / false for v1.00.
    std::array<float, 3> sonar_offset_m{};  // x, y, z
    std::uint8_t intensity_flag_raw = 0;    // byte 117 as read
    bool intensity_included = false;        // intensities follow the ranges
    bool intensity_flag_ignored = false;    // byte 117 = 1 but N = 256+2B (MB-System, §4.2)
    std::int32_t ping_latency_us = -1;      // bytes 118-119 x 100 us; -1 for v1.00
    std::int32_t data_latency_us = -1;      // bytes 120-121 x 100 us; -1 for v1.00
    std::uint8_t sample_rate = 0;           // 0 standard, 1 high
    std::uint8_t option_flags = 0;          // kOption* bits
    std::uint8_t pings_averaged = 0;
    std::int32_t center_ping_offset_us = 0;  // bytes 126-127 x 100 us
    float heave_m = 0.0f;                    // external, positive up
    std::uint8_t user_byte = 0;              // byte 132
    float altitude_m = 0.0f;
    std::uint8_t external_sensor_flags = 0;  // kExternal* bits
    float external_pitch_deg = 0.0f;
    float external_roll_deg = 0.0f;
    float external_heading_deg = 0.0f;
    std::uint8_t transmit_scan_flag = 0;  // 0 manual, 1 auto-scan
    float transmit_scan_angle_deg = 0.0f;
    // Byte order the decoder chose per float field, and which fields were implausible in
    // both orders (then the preferred order's value is passed on unfiltered).
    std::array<FloatOrder, kNumFloatFields> float_order{};
    std::uint16_t float_implausible_mask = 0;  // bit i = FloatField i

    // Beam block (§1.3): raw u16 counts. 0 = no detection.
    std::vector<std::uint16_t> range_counts;
    std::vector<std::uint16_t> intensities;  // empty unless intensity_included

    std::size_t num_beams() const { return range_counts.size(); }
    bool is_v110() const { return format_version >= kVersion110; }
    // theta_i in 0.01 deg, integer arithmetic (§1.5, §4.12): start + i * increment.
    std::int32_t BeamAngleCdeg(std::size_t i) const {
        return start_angle_cdeg + static_cast<std::int32_t>(i) * angle_increment_cdeg;
    }
    double BeamAngleDeg(std::size_t i) const { return BeamAngleCdeg(i) / 100.0; }
    double start_angle_deg() const { return start_angle_cdeg / 100.0; }
    double angle_increment_deg() const { return angle_increment_cdeg / 100.0; }
    // r_i = R_i * res_mm / 1000 (rolker convention, no sound-speed scaling; §1.5 [U]).
    double SlantRangeM(std::size_t i) const {
        return range_counts[i] * static_cast<double>(range_resolution_mm) / 1000.0;
    }
    // MB-System convention: additionally scaled by c/1500 when the header sound velocity is
    // valid (§1.5 [U]).
    double SlantRangeSoundSpeedScaledM(std::size_t i) const {
        const double scale =
            sound_velocity_valid ? sound_velocity_mps / kDefaultSoundVelocityMps : 1.0;
        return SlantRangeM(i) * scale;
    }
    bool has_detection(std::size_t i) const { return range_counts[i] != 0; }
    // Age of the transmit when the datagram left the topside PC, data - ping latency (§1.4);
    // -1 for v1.00 or when the latencies are inconsistent. Not valid in file playback.
    std::int32_t TransmitAgeAtSendUs() const {
        if (ping_latency_us < 0 || data_latency_us < ping_latency_us) return -1;
        return data_latency_us - ping_latency_us;
    }
    bool external_valid(std::uint8_t bit) const { return (external_sensor_flags & bit) != 0; }
};

// An MB-System comment record (§2.3): `83P`, version, N = 256, `##` at 6-7, text from 8.
struct Comment83P {
    std::uint8_t format_version = 0;
    std::array<char, kHeaderBytes - 8> text{};  // NUL padded
    std::string_view text_view() const {
        std::size_t n = 0;
        while (n < text.size() && text[n] != '\0') ++n;
        return std::string_view(text.data(), n);
    }
};

}  // namespace pitmap::protocol::deltat
