// SPDX-License-Identifier: MIT
// The survey file's ping and navigation records are a stated byte layout, not a struct's memory:
// a record's bytes are checked at the offsets survey_records.hpp documents, so reordering
// PingHeader's fields (or adding one) cannot change the file without failing here.
#include "processor/survey/survey_records.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <vector>

namespace pitmap::proc::survey::records {
namespace {

std::uint64_t U64At(const std::vector<std::uint8_t>& b, std::size_t at) {
    std::uint64_t v = 0;
    for (int i = 7; i >= 0; --i) v = (v << 8) | b.at(at + static_cast<std::size_t>(i));
    return v;
}
double F64At(const std::vector<std::uint8_t>& b, std::size_t at) {
    const std::uint64_t u = U64At(b, at);
    double d = 0;
    std::memcpy(&d, &u, 8);
    return d;
}

survey::PingHeader SamplePing() {
    survey::PingHeader p;
    p.utime_gps = 1'400'000'000'123'456;
    p.ping_number = 987'654;
    p.sound_speed_mps = 1487.25;
    p.sound_speed_valid = true;
    p.range_resolution_m = 0.0125;
    p.start_angle_deg = -60.0;
    p.angle_increment_deg = 0.5;
    p.profile_tilt_deg = 2.5;
    p.beam_offset = 0x01020304u;
    p.num_beams = 0x0506;
    p.aid_attitude_at_ping = true;
    p.aid_latitude_deg = 40.5;
    p.aid_longitude_deg = -7.75;
    p.aid_roll_deg = 1.25;
    p.aid_pitch_deg = -0.5;
    p.aid_heading_deg = 271.0;
    return p;
}

TEST(SurveyRecords, PingIsItsDocumentedLayout) {
    std::vector<std::uint8_t> b;
    ByteWriter w(b);
    WritePing(w, SamplePing());
    ASSERT_EQ(b.size(), kPingBytes);
    EXPECT_EQ(U64At(b, 0), 1'400'000'000'123'456u);
    EXPECT_EQ(U64At(b, 8), 987'654u);
    EXPECT_EQ(F64At(b, 16), 1487.25);
    EXPECT_EQ(b[24], 1);
    EXPECT_EQ(F64At(b, 25), 0.0125);
    EXPECT_EQ(F64At(b, 33), -60.0);
    EXPECT_EQ(F64At(b, 41), 0.5);
    EXPECT_EQ(F64At(b, 49), 2.5);
    EXPECT_EQ((std::vector<std::uint8_t>(b.begin() + 57, b.begin() + 63)),
              (std::vector<std::uint8_t>{0x04, 0x03, 0x02, 0x01, 0x06, 0x05}));
    EXPECT_EQ(b[63], 1);
    EXPECT_EQ(F64At(b, 64), 40.5);
    EXPECT_EQ(F64At(b, 72), -7.75);
    EXPECT_EQ(F64At(b, 80), 1.25);
    EXPECT_EQ(F64At(b, 88), -0.5);
    EXPECT_EQ(F64At(b, 96), 271.0);
}

TEST(SurveyRecords, PingRoundTripsAndAnyNonZeroByteIsTrue) {
    std::vector<std::uint8_t> b;
    ByteWriter w(b);
    survey::PingHeader in = SamplePing();
    in.aid_heading_deg = std::numeric_limits<double>::quiet_NaN();
    WritePing(w, in);
    b[24] = 7;  // a crafted file: still a bool, true
    ByteReader r(b.data(), b.size());
    const survey::PingHeader out = ReadPing(r);
    ASSERT_TRUE(r.ok());
    EXPECT_EQ(r.remaining(), 0u);
    EXPECT_EQ(out.utime_gps, in.utime_gps);
    EXPECT_EQ(out.ping_number, in.ping_number);
    EXPECT_EQ(out.sound_speed_mps, in.sound_speed_mps);
    EXPECT_TRUE(out.sound_speed_valid);
    EXPECT_EQ(out.range_resolution_m, in.range_resolution_m);
    EXPECT_EQ(out.start_angle_deg, in.start_angle_deg);
    EXPECT_EQ(out.angle_increment_deg, in.angle_increment_deg);
    EXPECT_EQ(out.profile_tilt_deg, in.profile_tilt_deg);
    EXPECT_EQ(out.beam_offset, in.beam_offset);
    EXPECT_EQ(out.num_beams, in.num_beams);
    EXPECT_TRUE(out.aid_attitude_at_ping);
    EXPECT_EQ(out.aid_latitude_deg, in.aid_latitude_deg);
    EXPECT_EQ(out.aid_longitude_deg, in.aid_longitude_deg);
    EXPECT_EQ(out.aid_roll_deg, in.aid_roll_deg);
    EXPECT_EQ(out.aid_pitch_deg, in.aid_pitch_deg);
    EXPECT_TRUE(std::isnan(out.aid_heading_deg));

    ByteReader short_reader(b.data(), b.size() - 1);
    ReadPing(short_reader);
    EXPECT_FALSE(short_reader.ok()) << "a short record fails the reader";
}

// Formats 1-4: the fields at the offsets the compilers gave PingHeader then, with padding.
TEST(SurveyRecords, LegacyPingReadsTheOldOffsets) {
    std::vector<std::uint8_t> b;
    ByteWriter w(b);
    const survey::PingHeader in = SamplePing();
    w.I64Le(in.utime_gps);
    w.I64Le(in.ping_number);
    w.F64Le(in.sound_speed_mps);
    w.U8(1);
    w.Zeros(7);
    w.F64Le(in.range_resolution_m);
    w.F64Le(in.start_angle_deg);
    w.F64Le(in.angle_increment_deg);
    w.F64Le(in.profile_tilt_deg);
    w.U32Le(in.beam_offset);
    w.U16Le(in.num_beams);
    w.U8(0);
    w.Zeros(1);
    for (double v : {in.aid_latitude_deg,
                     in.aid_longitude_deg,
                     in.aid_roll_deg,
                     in.aid_pitch_deg,
                     in.aid_heading_deg})
        w.F64Le(v);
    ASSERT_EQ(b.size(), kLegacyPingBytes);
    ByteReader r(b.data(), b.size());
    const survey::PingHeader out = ReadLegacyPing(r);
    ASSERT_TRUE(r.ok());
    EXPECT_EQ(r.remaining(), 0u);
    EXPECT_EQ(out.utime_gps, in.utime_gps);
    EXPECT_TRUE(out.sound_speed_valid);
    EXPECT_EQ(out.range_resolution_m, in.range_resolution_m);
    EXPECT_EQ(out.profile_tilt_deg, in.profile_tilt_deg);
    EXPECT_EQ(out.beam_offset, in.beam_offset);
    EXPECT_EQ(out.num_beams, in.num_beams);
    EXPECT_FALSE(out.aid_attitude_at_ping);
    EXPECT_EQ(out.aid_latitude_deg, in.aid_latitude_deg);
    EXPECT_EQ(out.aid_heading_deg, in.aid_heading_deg);
}

TEST(SurveyRecords, NavAndStdDevRoundTripInTheirSizes) {
    survey::NavSample s;
    s.utime_gps = 1'400'000'000'000'001;
    s.position = {40.1, -7.2, 412.5};
    s.roll_rad = 0.01;
    s.pitch_rad = -0.02;
    s.yaw_rad = 3.0;
    s.velocity_enu_mps = Eigen::Vector3d(1.5, -0.25, 0.125);
    s.ins_status = 3;
    s.position_type = 56;
    survey::NavStdDev d;
    d.utime_gps = s.utime_gps;
    d.north_m = 0.02f;
    d.east_m = 0.03f;
    d.up_m = 0.04f;
    d.roll_deg = 0.005f;
    d.pitch_deg = 0.006f;
    d.yaw_deg = 0.05f;
    std::vector<std::uint8_t> b;
    ByteWriter w(b);
    WriteNav(w, s);
    ASSERT_EQ(b.size(), kNavBytes);
    WriteStdDev(w, d);
    ASSERT_EQ(b.size(), kNavBytes + kStdDevBytes);
    EXPECT_EQ(F64At(b, 8), 40.1);  // latitude right after the time
    ByteReader r(b.data(), b.size());
    const survey::NavSample s2 = ReadNav(r);
    const survey::NavStdDev d2 = ReadStdDev(r);
    ASSERT_TRUE(r.ok());
    EXPECT_EQ(s2.utime_gps, s.utime_gps);
    EXPECT_EQ(s2.position.latitude_deg, s.position.latitude_deg);
    EXPECT_EQ(s2.position.height_m, s.position.height_m);
    EXPECT_EQ(s2.yaw_rad, s.yaw_rad);
    EXPECT_EQ(s2.velocity_enu_mps, s.velocity_enu_mps);
    EXPECT_EQ(s2.ins_status, 3);
    EXPECT_EQ(s2.position_type, 56);
    EXPECT_EQ(d2.utime_gps, d.utime_gps);
    EXPECT_EQ(d2.north_m, d.north_m);
    EXPECT_EQ(d2.yaw_deg, d.yaw_deg);
}

}  // namespace
}  // namespace pitmap::proc::survey::records
