// SPDX-License-Identifier: MIT
// 83P record decoder/encoder tests against the byte table of spec imagenex_deltat.md §1.2-1.4,
// §2.3 and the validation rules of §4. Records are hand-built byte by byte from the spec
// offsets (independent of the encoder) and also produced by the encoder for round trips.
// No real Delta T capture exists (spec §5): every record here is synthetic.
#include "common/protocol/deltat/record83p.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "common/gps_time.hpp"
#include "tests/protocol/deltat/deltat_test_util.hpp"

namespace pitmap::protocol::deltat {
namespace {

using test_util::MakePing;
using test_util::PutF32;
using test_util::PutText;
using test_util::PutU16Be;
using test_util::PutU32Be;

constexpr std::int64_t kUtime20240305_134507 = 1709646307000000;

// A v1.10 record of 480 beams without intensity, written from the §1.2 table.
std::vector<std::uint8_t> HandBuiltV110() {
    std::vector<std::uint8_t> b(256 + 2 * 480, 0);
    PutText(b, 0, "83P");
    b[3] = 10;
    PutU16Be(b, 4, 1216);
    PutText(b, 8, "05-MAR-2024");
    PutText(b, 20, "13:45:07");
    PutText(b, 29, ".12");
    PutText(b, 33, " 45.30.12345 N");
    PutText(b, 47, "073.15.50000 W");
    b[61] = 25;                             // 2.5 kn
    PutU16Be(b, 62, 1234);                  // 123.4 deg
    PutU16Be(b, 64, 0x8000 | (900 + 25));   // pitch +2.5
    PutU16Be(b, 66, 0x8000 | (900 - 105));  // roll -10.5
    PutU16Be(b, 68, 0x8000 | 3599);         // heading 359.9
    PutU16Be(b, 70, 480);
    PutU16Be(b, 72, 500);
    PutU16Be(b, 74, 120);
    PutU16Be(b, 76, 12000);  // S: beam 0 at -60 deg
    b[78] = 25;              // D: 0.25 deg
    PutU16Be(b, 79, 50);
    PutU16Be(b, 81, 260);
    PutU16Be(b, 83, 0x8000 | 14825);  // 1482.5 m/s
    PutU16Be(b, 85, 10);
    PutU16Be(b, 87, 120);
    PutU16Be(b, 89, 190);  // tilt +10
    PutU16Be(b, 91, 100);
    PutU32Be(b, 93, 0x01020304);
    PutF32(b, 100, 1.5f, true);
    PutF32(b, 104, -0.25f, true);
    PutF32(b, 108, 0.75f, false);  // per-field order: z little-endian
    PutText(b, 112, ".678");
    b[117] = 0;
    PutU16Be(b, 118, 25);
    PutU16Be(b, 120, 120);
    b[122] = 1;
    b[123] = 0x05;
    b[125] = 3;
    PutU16Be(b, 126, 40);
    PutF32(b, 128, 0.5f, true);
    b[132] = 0xAB;
    PutF32(b, 133, 12.5f, false);
    b[137] = 0x0F;
    PutF32(b, 138, 2.5f, true);
    PutF32(b, 142, -3.5f, true);
    PutF32(b, 146, 270.5f, true);
    b[150] = 1;
    PutF32(b, 151, -15.5f, false);
    for (std::size_t i = 0; i < 480; ++i) PutU16Be(b, 256 + 2 * i, static_cast<std::uint16_t>(i));
    return b;
}

Ping83P DecodeOk(const std::vector<std::uint8_t>& b, FloatOrderMemory& memory) {
    auto d = DecodeRecord83P(b, memory);
    EXPECT_TRUE(std::holds_alternative<Ping83P>(d))
        << (std::holds_alternative<DecodeError>(d) ? std::get<DecodeError>(d).message : "");
    if (!std::holds_alternative<Ping83P>(d)) return {};
    return std::get<Ping83P>(std::move(d));
}

Ping83P DecodeOk(const std::vector<std::uint8_t>& b) {
    FloatOrderMemory memory;
    return DecodeOk(b, memory);
}

DecodeError DecodeErr(const std::vector<std::uint8_t>& b) {
    auto d = DecodeRecord83P(b);
    EXPECT_TRUE(std::holds_alternative<DecodeError>(d));
    if (!std::holds_alternative<DecodeError>(d)) return {};
    return std::get<DecodeError>(d);
}

TEST(Record83P, HandBuiltV110EveryField) {
    const Ping83P p = DecodeOk(HandBuiltV110());
    EXPECT_EQ(p.format_version, 10);
    EXPECT_EQ(p.total_bytes, 1216);
    EXPECT_TRUE(p.header_time_valid);
    EXPECT_EQ(p.utime_sonar_header, kUtime20240305_134507 + 678000);  // ms, not hundredths
    EXPECT_DOUBLE_EQ(p.latitude_deg, 45.0 + 30.12345 / 60.0);
    EXPECT_DOUBLE_EQ(p.longitude_deg, -(73.0 + 15.5 / 60.0));
    EXPECT_DOUBLE_EQ(p.speed_over_ground_knots, 2.5);
    EXPECT_DOUBLE_EQ(p.course_over_ground_deg, 123.4);
    EXPECT_TRUE(p.internal_pitch_valid);
    EXPECT_DOUBLE_EQ(p.internal_pitch_deg, 2.5);
    EXPECT_TRUE(p.internal_roll_valid);
    EXPECT_DOUBLE_EQ(p.internal_roll_deg, -10.5);
    EXPECT_TRUE(p.internal_heading_valid);
    EXPECT_DOUBLE_EQ(p.internal_heading_deg, 359.9);
    EXPECT_EQ(p.num_beams(), 480u);
    EXPECT_EQ(p.samples_per_beam, 500);
    EXPECT_EQ(p.sector_size_deg, 120);
    EXPECT_EQ(p.start_angle_cdeg, -6000);
    EXPECT_EQ(p.angle_increment_cdeg, 25);
    EXPECT_EQ(p.BeamAngleCdeg(0), -6000);
    EXPECT_EQ(p.BeamAngleCdeg(240), 0);
    EXPECT_EQ(p.BeamAngleCdeg(479), 5975);  // +59.75 deg: not a symmetric fan (§1.5)
    EXPECT_DOUBLE_EQ(p.BeamAngleDeg(479), 59.75);
    EXPECT_DOUBLE_EQ(p.start_angle_deg(), -60.0);
    EXPECT_DOUBLE_EQ(p.angle_increment_deg(), 0.25);
    EXPECT_EQ(p.acoustic_range_m, 50);
    EXPECT_EQ(p.frequency_khz, 260);
    EXPECT_TRUE(p.sound_velocity_flag);
    EXPECT_TRUE(p.sound_velocity_valid);
    EXPECT_DOUBLE_EQ(p.sound_velocity_header_mps, 1482.5);
    EXPECT_DOUBLE_EQ(p.sound_velocity_mps, 1482.5);
    EXPECT_EQ(p.range_resolution_mm, 10);
    EXPECT_EQ(p.pulse_length_us, 120);
    EXPECT_DOUBLE_EQ(p.profile_tilt_deg, 10.0);
    EXPECT_FALSE(p.profile_tilt_837_style);
    EXPECT_EQ(p.repetition_rate_ms, 100);
    EXPECT_EQ(p.ping_number, 0x01020304u);
    EXPECT_EQ(p.sonar_offset_m[0], 1.5f);
    EXPECT_EQ(p.sonar_offset_m[1], -0.25f);
    EXPECT_EQ(p.sonar_offset_m[2], 0.75f);
    EXPECT_EQ(p.intensity_flag_raw, 0);
    EXPECT_FALSE(p.intensity_included);
    EXPECT_FALSE(p.intensity_flag_ignored);
    EXPECT_EQ(p.ping_latency_us, 2500);
    EXPECT_EQ(p.data_latency_us, 12000);
    EXPECT_EQ(p.sample_rate, 1);
    EXPECT_EQ(p.option_flags, kOptionRollCorrected | kOptionOverlapped);
    EXPECT_EQ(p.pings_averaged, 3);
    EXPECT_EQ(p.center_ping_offset_us, 4000);
    EXPECT_EQ(p.TransmitAgeAtSendUs(), 12000 - 2500);
    EXPECT_EQ(p.heave_m, 0.5f);
    EXPECT_EQ(p.user_byte, 0xAB);
    EXPECT_EQ(p.altitude_m, 12.5f);
    EXPECT_EQ(p.external_sensor_flags, 0x0F);
    EXPECT_TRUE(p.external_valid(kExternalHeaveValid));
    EXPECT_EQ(p.external_pitch_deg, 2.5f);
    EXPECT_EQ(p.external_roll_deg, -3.5f);
    EXPECT_EQ(p.external_heading_deg, 270.5f);
    EXPECT_EQ(p.transmit_scan_flag, 1);
    EXPECT_EQ(p.transmit_scan_angle_deg, -15.5f);
    EXPECT_EQ(p.float_order[static_cast<int>(FloatField::kOffsetX)], FloatOrder::kBig);
    EXPECT_EQ(p.float_order[static_cast<int>(FloatField::kOffsetZ)], FloatOrder::kLittle);
    EXPECT_EQ(p.float_order[static_cast<int>(FloatField::kAltitude)], FloatOrder::kLittle);
    EXPECT_EQ(p.float_order[static_cast<int>(FloatField::kExternalHeading)], FloatOrder::kBig);
    EXPECT_EQ(p.float_implausible_mask, 0);
    ASSERT_EQ(p.range_counts.size(), 480u);
    EXPECT_EQ(p.range_counts[0], 0);
    EXPECT_FALSE(p.has_detection(0));
    EXPECT_EQ(p.range_counts[479], 479);
    EXPECT_DOUBLE_EQ(p.SlantRangeM(479), 4.79);
    EXPECT_DOUBLE_EQ(p.SlantRangeSoundSpeedScaledM(479), 4.79 * 1482.5 / 1500.0);
    EXPECT_TRUE(p.intensities.empty());
}

TEST(Record83P, HandBuiltV100IgnoresBytes100To255) {
    std::vector<std::uint8_t> b = HandBuiltV110();
    b[3] = 0;
    for (std::size_t i = 100; i < 256; ++i) b[i] = 0xEE;
    b[117] = 1;  // ignored in v1.00: no intensity
    const Ping83P p = DecodeOk(b);
    EXPECT_EQ(p.format_version, 0);
    EXPECT_EQ(p.utime_sonar_header, kUtime20240305_134507 + 120000);  // hundredths
    EXPECT_FALSE(p.intensity_included);
    EXPECT_EQ(p.intensity_flag_raw, 0);
    EXPECT_EQ(p.ping_latency_us, -1);
    EXPECT_EQ(p.data_latency_us, -1);
    EXPECT_EQ(p.TransmitAgeAtSendUs(), -1);
    EXPECT_EQ(p.sonar_offset_m[0], 0.0f);
    EXPECT_EQ(p.altitude_m, 0.0f);
    EXPECT_EQ(p.external_sensor_flags, 0);
    EXPECT_EQ(p.ping_number, 0x01020304u);
    // v1.00 with N = 256 + 4B is inconsistent: the flag does not exist in v1.00.
    std::vector<std::uint8_t> c(256 + 4 * 120, 0);
    PutText(c, 0, "83P");
    PutU16Be(c, 4, static_cast<std::uint16_t>(c.size()));
    PutU16Be(c, 70, 120);
    c[117] = 1;
    EXPECT_EQ(DecodeErr(c).kind, DecodeErrorKind::kLengthMismatch);
}

TEST(Record83P, SoundVelocityBit) {
    auto b = HandBuiltV110();
    PutU16Be(b, 83, 14825);  // V clear -> 1500, not valid
    Ping83P p = DecodeOk(b);
    EXPECT_FALSE(p.sound_velocity_flag);
    EXPECT_FALSE(p.sound_velocity_valid);
    EXPECT_DOUBLE_EQ(p.sound_velocity_mps, 1500.0);
    EXPECT_DOUBLE_EQ(p.sound_velocity_header_mps, 0.0);
    PutU16Be(b, 83, 0x8000 | 18000);  // 1800 m/s: implausible -> 1500 (§4.7)
    p = DecodeOk(b);
    EXPECT_TRUE(p.sound_velocity_flag);
    EXPECT_FALSE(p.sound_velocity_valid);
    EXPECT_DOUBLE_EQ(p.sound_velocity_header_mps, 1800.0);
    EXPECT_DOUBLE_EQ(p.sound_velocity_mps, 1500.0);
    EXPECT_DOUBLE_EQ(p.SlantRangeSoundSpeedScaledM(479), p.SlantRangeM(479));
    PutU16Be(b, 83, 0x8000 | 13000);  // 1300.0 is inside the window
    p = DecodeOk(b);
    EXPECT_TRUE(p.sound_velocity_valid);
    EXPECT_DOUBLE_EQ(p.sound_velocity_mps, 1300.0);
}

TEST(Record83P, AttitudeBit15) {
    auto b = HandBuiltV110();
    PutU16Be(b, 64, 925);  // bit15 clear: not supplied
    PutU16Be(b, 66, 0);
    PutU16Be(b, 68, 0x8000);  // valid heading 0.0
    const Ping83P p = DecodeOk(b);
    EXPECT_FALSE(p.internal_pitch_valid);
    EXPECT_TRUE(std::isnan(p.internal_pitch_deg));
    EXPECT_FALSE(p.internal_roll_valid);
    EXPECT_TRUE(std::isnan(p.internal_roll_deg));
    EXPECT_TRUE(p.internal_heading_valid);
    EXPECT_DOUBLE_EQ(p.internal_heading_deg, 0.0);
    PutU16Be(b, 64, 0x8000);  // valid raw 0 -> -90.0
    EXPECT_DOUBLE_EQ(DecodeOk(b).internal_pitch_deg, -90.0);
}

TEST(Record83P, TiltRules) {
    auto b = HandBuiltV110();
    PutU16Be(b, 89, 0);  // MB-System: raw 0 -> 0 deg
    EXPECT_DOUBLE_EQ(DecodeOk(b).profile_tilt_deg, 0.0);
    PutU16Be(b, 89, 180);
    EXPECT_DOUBLE_EQ(DecodeOk(b).profile_tilt_deg, 0.0);
    PutU16Be(b, 89, 170);
    EXPECT_DOUBLE_EQ(DecodeOk(b).profile_tilt_deg, -10.0);
    PutU16Be(b, 89, 0x8000 | 1855);  // 837 style: (1855/10) - 180 = 5.5
    const Ping83P p = DecodeOk(b);
    EXPECT_TRUE(p.profile_tilt_837_style);
    EXPECT_DOUBLE_EQ(p.profile_tilt_deg, 5.5);
    // Both styles re-encode to the same bytes.
    const auto again = EncodeRecord83P(p);
    ASSERT_EQ(again.size(), b.size());
    EXPECT_EQ(again[89], 0x80 | (1855 >> 8));
    EXPECT_EQ(again[90], 1855 & 0xFF);
}

TEST(Record83P, LatitudeStrings) {
    EXPECT_DOUBLE_EQ(ParseLatitudeText(" 45.30.12345 N"), 45.0 + 30.12345 / 60.0);
    EXPECT_DOUBLE_EQ(ParseLatitudeText("_45_30.12345_S"), -(45.0 + 30.12345 / 60.0));
    EXPECT_DOUBLE_EQ(ParseLatitudeText(std::string_view(" 45\0"
                                                        "30\0"
                                                        "12345\0N",
                                                        14)),
                     45.0 + 30.12345 / 60.0);
    EXPECT_DOUBLE_EQ(ParseLatitudeText(" 45. 5.12345 S"), -(45.0 + 5.12345 / 60.0));
    EXPECT_DOUBLE_EQ(ParseLatitudeText("_ 5_ 5.00000_N"), 5.0 + 5.0 / 60.0);
    EXPECT_TRUE(std::isnan(ParseLatitudeText("              ")));
    EXPECT_TRUE(
        std::isnan(ParseLatitudeText(std::string_view("\0\0\0\0\0\0\0\0\0\0\0\0\0\0", 14))));
    EXPECT_TRUE(std::isnan(ParseLatitudeText(" 00.00.00000 N")));  // all zero: no GNSS
    EXPECT_TRUE(std::isnan(ParseLatitudeText("______________")));
    EXPECT_TRUE(std::isnan(ParseLatitudeText(" 45.60.00000 N")));  // minutes >= 60
    EXPECT_TRUE(std::isnan(ParseLatitudeText(" 91.00.00000 N")));
    EXPECT_TRUE(std::isnan(ParseLatitudeText(" 45.30.12345 E")));  // wrong hemisphere letter
    EXPECT_TRUE(std::isnan(ParseLatitudeText(" 4x.30.12345 N")));
    EXPECT_TRUE(std::isnan(ParseLatitudeText(" 45.30.1 345 N")));  // pad inside fraction
    EXPECT_TRUE(std::isnan(ParseLatitudeText(" 45.30")));          // short
}

TEST(Record83P, LongitudeStrings) {
    EXPECT_DOUBLE_EQ(ParseLongitudeText("073.15.50000 W"), -(73.0 + 15.5 / 60.0));
    EXPECT_DOUBLE_EQ(ParseLongitudeText("179_59.99999_E"), 179.0 + 59.99999 / 60.0);
    EXPECT_DOUBLE_EQ(ParseLongitudeText("  7. 1.00000 E"), 7.0 + 1.0 / 60.0);
    EXPECT_TRUE(std::isnan(ParseLongitudeText("000.00.00000 E")));
    EXPECT_TRUE(std::isnan(ParseLongitudeText("181.00.00000 E")));
    EXPECT_TRUE(std::isnan(ParseLongitudeText("180.00.00001 W")));
    EXPECT_TRUE(std::isnan(ParseLongitudeText("073.15.50000 N")));
}

TEST(Record83P, NavStringsInRecord) {
    auto b = HandBuiltV110();
    PutText(b, 33, "______________");
    PutText(b, 47, std::string_view("\0\0\0\0\0\0\0\0\0\0\0\0\0\0", 14));
    Ping83P p = DecodeOk(b);
    EXPECT_TRUE(std::isnan(p.latitude_deg));
    EXPECT_TRUE(std::isnan(p.longitude_deg));
    PutText(b, 33, "_12_ 3.40000_S");
    PutText(b, 47, "123_45.00000_E");
    p = DecodeOk(b);
    EXPECT_DOUBLE_EQ(p.latitude_deg, -(12.0 + 3.4 / 60.0));
    EXPECT_DOUBLE_EQ(p.longitude_deg, 123.75);
}

TEST(Record83P, MonthParsing) {
    const char* months[] = {
        "JAN", "FEB", "MAR", "APR", "MAY", "JUN", "JUL", "AUG", "SEP", "OCT", "NOV", "DEC"};
    for (int m = 0; m < 12; ++m) {
        const std::string date = std::string("01-") + months[m] + "-2023";
        const auto t = ParseHeaderClock(date, "00:00:00", ".00");
        ASSERT_TRUE(t.has_value()) << date;
        UtcCalendar c;
        c.year = 2023;
        c.month = m + 1;
        c.day = 1;
        EXPECT_EQ(*t, *UnixFromUtcCalendar(c)) << date;
    }
    EXPECT_EQ(ParseHeaderClock("05-mar-2024", "13:45:07", ".678"),
              kUtime20240305_134507 + 678000);  // case-insensitive
    EXPECT_EQ(ParseHeaderClock("05-Mar-2024", "13:45:07", ".12"), kUtime20240305_134507 + 120000);
    EXPECT_FALSE(ParseHeaderClock("05-XYZ-2024", "13:45:07", ".12").has_value());
    EXPECT_FALSE(ParseHeaderClock("30-FEB-2024", "13:45:07", ".12").has_value());
    EXPECT_FALSE(ParseHeaderClock("05-MAR-2024", "24:00:00", ".12").has_value());
    EXPECT_FALSE(ParseHeaderClock("05-MAR-2024", "13:45:07", ".1").has_value());
    EXPECT_FALSE(ParseHeaderClock("05-MAR-2024", "13:45:07", ".1x").has_value());
    EXPECT_FALSE(ParseHeaderClock("           ", "        ", "   ").has_value());
    EXPECT_FALSE(ParseHeaderClock("5-MAR-2024", "13:45:07", ".12").has_value());
}

TEST(Record83P, MillisecondsVersusHundredths) {
    auto b = HandBuiltV110();
    // v1.10: ms wins over hundredths.
    EXPECT_EQ(DecodeOk(b).utime_sonar_header, kUtime20240305_134507 + 678000);
    // v1.10 with a blank ms field falls back to hundredths.
    PutText(b, 112, std::string_view("\0\0\0\0\0", 5));
    EXPECT_EQ(DecodeOk(b).utime_sonar_header, kUtime20240305_134507 + 120000);
    // Neither parsable: clock not valid, utime 0.
    PutText(b, 29, "abc");
    Ping83P p = DecodeOk(b);
    EXPECT_FALSE(p.header_time_valid);
    EXPECT_EQ(p.utime_sonar_header, 0);
    // Unparsable date.
    b = HandBuiltV110();
    PutText(b, 8, "05-QQQ-2024");
    p = DecodeOk(b);
    EXPECT_FALSE(p.header_time_valid);
    EXPECT_EQ(p.utime_sonar_header, 0);
}

TEST(Record83P, SetHeaderHelpers) {
    Ping83P p;
    p.format_version = 10;
    SetHeaderTime(p, kUtime20240305_134507 + 678901);
    EXPECT_EQ(std::string(p.date_text.data()), "05-MAR-2024");
    EXPECT_EQ(std::string(p.time_text.data()), "13:45:07");
    EXPECT_EQ(std::string(p.hundredths_text.data()), ".67");
    EXPECT_EQ(std::string(p.milliseconds_text.data(), 4), ".678");
    EXPECT_EQ(p.utime_sonar_header, kUtime20240305_134507 + 678000);
    p.format_version = 0;
    SetHeaderTime(p, kUtime20240305_134507 + 678901);
    EXPECT_EQ(p.utime_sonar_header, kUtime20240305_134507 + 670000);
    SetHeaderLatitude(p, 45.5);
    EXPECT_EQ(std::string(p.latitude_text.data(), 14), " 45.30.00000 N");
    SetHeaderLatitude(p, -0.5);
    EXPECT_EQ(std::string(p.latitude_text.data(), 14), " 00.30.00000 S");
    EXPECT_DOUBLE_EQ(p.latitude_deg, -0.5);
    SetHeaderLongitude(p, -73.999999999);  // rounds up to 74 deg, never 60 minutes
    EXPECT_EQ(std::string(p.longitude_text.data(), 14), "074.00.00000 W");
    SetHeaderLongitude(p, std::nan(""));
    EXPECT_EQ(std::string(p.longitude_text.data(), 14), "              ");
    EXPECT_TRUE(std::isnan(p.longitude_deg));
}

// Field-by-field comparison, NaN equal to NaN.
void ExpectSamePing(const Ping83P& a, const Ping83P& b) {
    const auto same = [](double x, double y) { return (std::isnan(x) && std::isnan(y)) || x == y; };
    EXPECT_EQ(a.format_version, b.format_version);
    EXPECT_EQ(a.date_text, b.date_text);
    EXPECT_EQ(a.time_text, b.time_text);
    EXPECT_EQ(a.hundredths_text, b.hundredths_text);
    EXPECT_EQ(a.milliseconds_text, b.milliseconds_text);
    EXPECT_EQ(a.header_time_valid, b.header_time_valid);
    EXPECT_EQ(a.utime_sonar_header, b.utime_sonar_header);
    EXPECT_EQ(a.latitude_text, b.latitude_text);
    EXPECT_EQ(a.longitude_text, b.longitude_text);
    EXPECT_TRUE(same(a.latitude_deg, b.latitude_deg));
    EXPECT_TRUE(same(a.longitude_deg, b.longitude_deg));
    EXPECT_DOUBLE_EQ(a.speed_over_ground_knots, b.speed_over_ground_knots);
    EXPECT_DOUBLE_EQ(a.course_over_ground_deg, b.course_over_ground_deg);
    EXPECT_EQ(a.internal_pitch_valid, b.internal_pitch_valid);
    EXPECT_EQ(a.internal_roll_valid, b.internal_roll_valid);
    EXPECT_EQ(a.internal_heading_valid, b.internal_heading_valid);
    EXPECT_TRUE(same(a.internal_pitch_deg, b.internal_pitch_deg));
    EXPECT_TRUE(same(a.internal_roll_deg, b.internal_roll_deg));
    EXPECT_TRUE(same(a.internal_heading_deg, b.internal_heading_deg));
    EXPECT_EQ(a.samples_per_beam, b.samples_per_beam);
    EXPECT_EQ(a.sector_size_deg, b.sector_size_deg);
    EXPECT_EQ(a.start_angle_cdeg, b.start_angle_cdeg);
    EXPECT_EQ(a.angle_increment_cdeg, b.angle_increment_cdeg);
    EXPECT_EQ(a.acoustic_range_m, b.acoustic_range_m);
    EXPECT_EQ(a.frequency_khz, b.frequency_khz);
    EXPECT_EQ(a.sound_velocity_flag, b.sound_velocity_flag);
    EXPECT_DOUBLE_EQ(a.sound_velocity_header_mps, b.sound_velocity_header_mps);
    EXPECT_DOUBLE_EQ(a.sound_velocity_mps, b.sound_velocity_mps);
    EXPECT_EQ(a.sound_velocity_valid, b.sound_velocity_valid);
    EXPECT_EQ(a.range_resolution_mm, b.range_resolution_mm);
    EXPECT_EQ(a.pulse_length_us, b.pulse_length_us);
    EXPECT_DOUBLE_EQ(a.profile_tilt_deg, b.profile_tilt_deg);
    EXPECT_EQ(a.repetition_rate_ms, b.repetition_rate_ms);
    EXPECT_EQ(a.ping_number, b.ping_number);
    EXPECT_EQ(a.sonar_offset_m, b.sonar_offset_m);
    EXPECT_EQ(a.intensity_included, b.intensity_included);
    EXPECT_EQ(a.ping_latency_us, b.ping_latency_us);
    EXPECT_EQ(a.data_latency_us, b.data_latency_us);
    EXPECT_EQ(a.sample_rate, b.sample_rate);
    EXPECT_EQ(a.option_flags, b.option_flags);
    EXPECT_EQ(a.pings_averaged, b.pings_averaged);
    EXPECT_EQ(a.center_ping_offset_us, b.center_ping_offset_us);
    EXPECT_EQ(a.heave_m, b.heave_m);
    EXPECT_EQ(a.user_byte, b.user_byte);
    EXPECT_EQ(a.altitude_m, b.altitude_m);
    EXPECT_EQ(a.external_sensor_flags, b.external_sensor_flags);
    EXPECT_EQ(a.external_pitch_deg, b.external_pitch_deg);
    EXPECT_EQ(a.external_roll_deg, b.external_roll_deg);
    EXPECT_EQ(a.external_heading_deg, b.external_heading_deg);
    EXPECT_EQ(a.transmit_scan_flag, b.transmit_scan_flag);
    EXPECT_EQ(a.transmit_scan_angle_deg, b.transmit_scan_angle_deg);
    EXPECT_EQ(a.range_counts, b.range_counts);
    EXPECT_EQ(a.intensities, b.intensities);
}

struct RoundTripCase {
    std::size_t beams;
    bool intensity;
    std::uint8_t version;
    FloatOrder order;
};

class RoundTrip : public ::testing::TestWithParam<RoundTripCase> {};

TEST_P(RoundTrip, EncodeDecodeEncode) {
    const RoundTripCase c = GetParam();
    const Ping83P original = MakePing(c.beams, c.intensity, c.version);
    EncodeOptions options;
    options.float_order = c.order;
    const auto bytes = EncodeRecord83P(original, options);
    const bool has_intensity = c.intensity && c.version >= 10;
    ASSERT_EQ(bytes.size(), 256 + (has_intensity ? 4 : 2) * c.beams);
    EXPECT_EQ(bytes[4] << 8 | bytes[5], static_cast<int>(bytes.size()));
    EXPECT_EQ(bytes[70] << 8 | bytes[71], static_cast<int>(c.beams));
    FloatOrderMemory memory;
    const Ping83P decoded = DecodeOk(bytes, memory);
    ExpectSamePing(original, decoded);
    EXPECT_EQ(decoded.total_bytes, bytes.size());
    if (c.version >= 10) {
        for (std::size_t f = 0; f < kNumFloatFields; ++f) {
            EXPECT_EQ(decoded.float_order[f], c.order) << "field " << f;
            EXPECT_EQ(memory.order[f], c.order) << "field " << f;
        }
    }
    // Re-encoding the decoded ping gives the same bytes.
    EXPECT_EQ(EncodeRecord83P(decoded, options), bytes);
}

std::vector<RoundTripCase> AllRoundTripCases() {
    std::vector<RoundTripCase> cases;
    for (std::size_t beams : {120u, 240u, 480u}) {
        for (bool intensity : {false, true}) {
            for (std::uint8_t version : {std::uint8_t{0}, std::uint8_t{10}}) {
                for (FloatOrder order : {FloatOrder::kBig, FloatOrder::kLittle}) {
                    if (version == 0 && (intensity || order == FloatOrder::kLittle)) continue;
                    cases.push_back({beams, intensity, version, order});
                }
            }
        }
    }
    return cases;
}

std::string RoundTripName(const ::testing::TestParamInfo<RoundTripCase>& param) {
    const auto& c = param.param;
    return "B" + std::to_string(c.beams) + (c.intensity ? "_int" : "_noint") + "_v" +
           std::to_string(c.version) + (c.order == FloatOrder::kBig ? "_be" : "_le");
}

INSTANTIATE_TEST_SUITE_P(AllLayouts,
                         RoundTrip,
                         ::testing::ValuesIn(AllRoundTripCases()),
                         RoundTripName);

TEST(Record83P, Collision1216Bytes) {
    const auto a = EncodeRecord83P(MakePing(480, false, 10));
    const auto b = EncodeRecord83P(MakePing(240, true, 10));
    ASSERT_EQ(a.size(), 1216u);
    ASSERT_EQ(b.size(), 1216u);
    const Ping83P pa = DecodeOk(a);
    const Ping83P pb = DecodeOk(b);
    EXPECT_EQ(pa.num_beams(), 480u);
    EXPECT_FALSE(pa.intensity_included);
    EXPECT_TRUE(pa.intensities.empty());
    EXPECT_EQ(pa.range_counts[479], MakePing(480, false, 10).range_counts[479]);
    EXPECT_EQ(pb.num_beams(), 240u);
    EXPECT_TRUE(pb.intensity_included);
    ASSERT_EQ(pb.intensities.size(), 240u);
    EXPECT_EQ(pb.intensities[239], (239 * 11 + 5) % 1000);
    // Swapping the flag alone makes both inconsistent.
    auto a_flag = a;
    a_flag[117] = 1;  // 480 beams, flag 1, N = 256+2B: MB-System case, still no intensity
    EXPECT_TRUE(DecodeOk(a_flag).intensity_flag_ignored);
    auto b_noflag = b;
    b_noflag[117] = 0;  // 240 beams, N = 256+4B without the flag
    EXPECT_EQ(DecodeErr(b_noflag).kind, DecodeErrorKind::kLengthMismatch);
    EXPECT_EQ(DecodeErr(b_noflag).offset, 4u);
}

TEST(Record83P, MbSystemShortLengthWithFlag) {
    const Ping83P ping = MakePing(240, true, 10);
    EncodeOptions options;
    options.mbsystem_short_length = true;
    const auto bytes = EncodeRecord83P(ping, options);
    ASSERT_EQ(bytes.size(), 256u + 2 * 240);
    EXPECT_EQ(bytes[117], 1);
    const Ping83P p = DecodeOk(bytes);
    EXPECT_EQ(p.intensity_flag_raw, 1);
    EXPECT_FALSE(p.intensity_included);
    EXPECT_TRUE(p.intensity_flag_ignored);
    EXPECT_TRUE(p.intensities.empty());
    EXPECT_EQ(p.range_counts, ping.range_counts);
}

TEST(Record83P, LengthAndBeamValidation) {
    auto b = EncodeRecord83P(MakePing(120, false, 10));
    ASSERT_EQ(b.size(), 496u);
    auto bad = b;
    PutU16Be(bad, 70, 0);
    EXPECT_EQ(DecodeErr(bad).kind, DecodeErrorKind::kBadBeamCount);
    EXPECT_EQ(DecodeErr(bad).offset, 70u);
    bad = b;
    PutU16Be(bad, 70, 481);
    EXPECT_EQ(DecodeErr(bad).kind, DecodeErrorKind::kBadBeamCount);
    bad = b;
    PutU16Be(bad, 70, 121);  // N no longer 256+2B
    EXPECT_EQ(DecodeErr(bad).kind, DecodeErrorKind::kLengthMismatch);
    bad = b;
    PutU16Be(bad, 4, 255);
    EXPECT_EQ(DecodeErr(bad).kind, DecodeErrorKind::kBadLength);
    EXPECT_EQ(DecodeErr(bad).offset, 4u);
    bad = b;
    PutU16Be(bad, 4, 2178);
    EXPECT_EQ(DecodeErr(bad).kind, DecodeErrorKind::kBadLength);
    bad = b;
    bad[2] = 'Q';
    EXPECT_EQ(DecodeErr(bad).kind, DecodeErrorKind::kBadMarker);
    bad[2] = 'B';
    EXPECT_EQ(DecodeErr(bad).kind, DecodeErrorKind::kUnsupported);
    bad = b;
    bad.push_back(0);
    EXPECT_EQ(DecodeErr(bad).kind, DecodeErrorKind::kTrailingBytes);
    EXPECT_EQ(DecodeErr(bad).offset, 496u);
    bad = b;
    bad.pop_back();
    EXPECT_EQ(DecodeErr(bad).kind, DecodeErrorKind::kTruncated);
    EXPECT_EQ(DecodeErr(bad).offset, 495u);
    bad.resize(100);  // cannot even see B
    EXPECT_EQ(DecodeErr(bad).kind, DecodeErrorKind::kTruncated);
    bad.resize(2);
    EXPECT_EQ(DecodeErr(bad).kind, DecodeErrorKind::kTruncated);
    EXPECT_EQ(DecodeErr({}).kind, DecodeErrorKind::kTruncated);
    // Version 5 is read with the v1.00 layout (documented decision).
    bad = b;
    bad[3] = 5;
    const Ping83P p = DecodeOk(bad);
    EXPECT_EQ(p.format_version, 5);
    EXPECT_EQ(p.ping_latency_us, -1);
}

TEST(Record83P, EncoderRejectsUnencodablePings) {
    Ping83P p = MakePing(120, true, 10);
    p.intensities.pop_back();
    EXPECT_TRUE(EncodeRecord83P(p).empty());
    p = MakePing(120, false, 10);
    p.range_counts.clear();
    EXPECT_TRUE(EncodeRecord83P(p).empty());
    p.range_counts.resize(481);
    std::vector<std::uint8_t> out = {1, 2};
    EXPECT_FALSE(EncodeRecord83P(p, {}, out));
    EXPECT_EQ(out.size(), 2u);
}

TEST(Record83P, FloatByteOrderMemory) {
    auto b = HandBuiltV110();
    // Heading bytes 41 20 00 41: BE 10.00006, LE 8.00787 — both plausible.
    const std::uint8_t ambiguous[4] = {0x41, 0x20, 0x00, 0x41};
    for (int i = 0; i < 4; ++i) b[146 + i] = ambiguous[i];
    FloatOrderMemory fresh;
    Ping83P p = DecodeOk(b, fresh);
    EXPECT_NEAR(p.external_heading_deg, 10.00006f, 1e-4);  // default: big-endian
    EXPECT_EQ(fresh.Get(FloatField::kExternalHeading), FloatOrder::kUnknown);  // not learned
    // A stream that has seen unambiguous little-endian headings keeps reading little-endian.
    auto le = HandBuiltV110();
    PutF32(le, 146, 270.5f, false);
    FloatOrderMemory memory;
    EXPECT_EQ(DecodeOk(le, memory).external_heading_deg, 270.5f);
    EXPECT_EQ(memory.Get(FloatField::kExternalHeading), FloatOrder::kLittle);
    p = DecodeOk(b, memory);
    EXPECT_NEAR(p.external_heading_deg, 8.00787f, 1e-4);
    EXPECT_EQ(p.float_order[static_cast<int>(FloatField::kExternalHeading)], FloatOrder::kLittle);
    // Altitude decided little-endian from the hand-built record, offsets big-endian.
    EXPECT_EQ(memory.Get(FloatField::kAltitude), FloatOrder::kLittle);
    EXPECT_EQ(memory.Get(FloatField::kOffsetX), FloatOrder::kBig);
    // Only one order plausible: the memory is overridden and updated.
    PutF32(b, 146, 90.25f, true);
    p = DecodeOk(b, memory);
    EXPECT_EQ(p.external_heading_deg, 90.25f);
    EXPECT_EQ(memory.Get(FloatField::kExternalHeading), FloatOrder::kBig);
    // Implausible both ways: passed on in the preferred order and flagged.
    const std::uint8_t junk[4] = {0x7F, 0xC0, 0x00, 0x7F};  // BE NaN, LE 1.7e38
    for (int i = 0; i < 4; ++i) b[133 + i] = junk[i];
    p = DecodeOk(b, memory);
    EXPECT_EQ(p.float_implausible_mask, 1u << static_cast<int>(FloatField::kAltitude));
    EXPECT_FLOAT_EQ(p.altitude_m, 1.7114068e38f);  // memory says little
    // Exact zero: same in both orders, no decision.
    PutF32(b, 100, 0.0f, true);
    p = DecodeOk(b, memory);
    EXPECT_EQ(p.sonar_offset_m[0], 0.0f);
    EXPECT_EQ(p.float_order[0], FloatOrder::kUnknown);
    EXPECT_EQ(memory.Get(FloatField::kOffsetX), FloatOrder::kBig);
    // Out-of-window values pick the other order: 150 m altitude offset is > 100 m.
    auto w = HandBuiltV110();
    PutF32(w, 104, 250.0f, true);
    p = DecodeOk(w);
    EXPECT_EQ(p.float_implausible_mask, 1u << static_cast<int>(FloatField::kOffsetY));
}

TEST(Record83P, CommentRecords) {
    const auto bytes = EncodeComment83P("processed by mbcopy");
    ASSERT_EQ(bytes.size(), 256u);
    EXPECT_EQ(bytes[6], '#');
    EXPECT_EQ(bytes[7], '#');
    const auto d = DecodeRecord83P(bytes);
    ASSERT_TRUE(std::holds_alternative<Comment83P>(d));
    EXPECT_EQ(std::get<Comment83P>(d).text_view(), "processed by mbcopy");
    EXPECT_EQ(std::get<Comment83P>(d).format_version, 10);
    Ping83P scratch;
    FloatOrderMemory memory;
    const auto k = DecodeRecord83PInto(bytes, memory, scratch);
    ASSERT_TRUE(std::holds_alternative<RecordKind>(k));
    EXPECT_EQ(std::get<RecordKind>(k), RecordKind::kComment);
    // A comment longer than the record keeps a terminating NUL.
    const auto long_comment = DecodeRecord83P(EncodeComment83P(std::string(400, 'x')));
    EXPECT_EQ(std::get<Comment83P>(long_comment).text_view().size(), 247u);
    // `##` with N != 256 is not a comment.
    auto not_comment = bytes;
    PutU16Be(not_comment, 4, 496);
    not_comment.resize(496);
    EXPECT_EQ(DecodeErr(not_comment).kind, DecodeErrorKind::kBadBeamCount);
}

TEST(Record83P, DecodeIntoReusesVectors) {
    const auto big = EncodeRecord83P(MakePing(480, true, 10));
    const auto small = EncodeRecord83P(MakePing(120, false, 10, 9));
    Ping83P p;
    FloatOrderMemory memory;
    ASSERT_TRUE(std::holds_alternative<RecordKind>(DecodeRecord83PInto(big, memory, p)));
    const std::uint16_t* ranges = p.range_counts.data();
    const std::uint16_t* amps = p.intensities.data();
    ASSERT_TRUE(std::holds_alternative<RecordKind>(DecodeRecord83PInto(small, memory, p)));
    EXPECT_EQ(p.num_beams(), 120u);
    EXPECT_TRUE(p.intensities.empty());
    EXPECT_EQ(p.ping_number, 9u);
    ASSERT_TRUE(std::holds_alternative<RecordKind>(DecodeRecord83PInto(big, memory, p)));
    EXPECT_EQ(p.range_counts.data(), ranges);
    EXPECT_EQ(p.intensities.data(), amps);
    EXPECT_EQ(p.intensities.size(), 480u);
}

}  // namespace
}  // namespace pitmap::protocol::deltat
