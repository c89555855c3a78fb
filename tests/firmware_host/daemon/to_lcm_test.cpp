// SPDX-License-Identifier: MIT
// to_lcm: every lcmtype field filled from the protocol structs, absent values as the .lcm
// comments say (-1 / NaN), channel names, and an encode/decode round trip of each type.
#include "firmware_host/daemon/to_lcm.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "common/gps_time.hpp"
#include "common/protocol/deltat/record83p.hpp"

namespace pitmap::acq {
namespace {

namespace nv = protocol::novatel;
namespace dt = protocol::deltat;

constexpr std::int64_t kHost = 1'700'000'000'123'456;

nv::Header LongHeader(std::uint16_t id) {
    nv::Header h;
    h.kind = nv::HeaderKind::kLongBinary;
    h.message_id = id;
    h.port_address = 0x20;
    h.sequence = 7;
    h.idle_time = 101;
    h.time_status = nv::TimeStatus::kFineSteering;
    h.gps_week = 2300;
    h.gps_ms = 345'678'900;
    h.receiver_status = 0x02000020;
    h.reserved = 0xABCD;
    h.sw_build = 16809;
    return h;
}

const std::int64_t kHeaderGps = GpsUtimeFromWeekMs(2300, 345'678'900);

// Decoding what we encoded gives the same lcm struct (checks getEncodedSize/encode use).
template <typename T>
T RoundTrip(const T& in) {
    const std::vector<std::uint8_t> bytes = EncodeLcm(in);
    T out;
    EXPECT_EQ(out.decode(bytes.data(), 0, static_cast<int>(bytes.size())),
              static_cast<int>(bytes.size()));
    return out;
}

TEST(ToLcmTest, ChannelNameUpperCasesTheId) {
    EXPECT_EQ(ChannelName(kChannelInsPva, "novatel_com1"), "INS_PVA_NOVATEL_COM1");
    EXPECT_EQ(ChannelName(kChannelRaw, "Deltat-udp2"), "RAW_DELTAT-UDP2");
}

TEST(ToLcmTest, LongHeaderFillsEveryField) {
    const auto h = ToLcm(LongHeader(42));
    EXPECT_EQ(h.message_id, 42);
    EXPECT_EQ(h.header_kind, pitmap::novatel_header_t::KIND_LONG_BINARY);
    EXPECT_EQ(h.is_response, 0);
    EXPECT_EQ(h.port, 0x20);
    EXPECT_EQ(h.sequence, 7);
    EXPECT_FLOAT_EQ(h.idle_percent, 50.5f);
    EXPECT_EQ(h.time_status, 180);
    EXPECT_EQ(h.gps_week, 2300);
    EXPECT_EQ(h.gps_ms, 345'678'900);
    EXPECT_EQ(h.receiver_status, 0x02000020);
    EXPECT_EQ(h.reserved, 0xABCD);
    EXPECT_EQ(h.sw_build, 16809);
}

TEST(ToLcmTest, ShortHeaderMarksAbsentFields) {
    nv::Header s;
    s.kind = nv::HeaderKind::kShortBinary;
    s.message_id = 508;
    s.gps_week = 2300;
    s.gps_ms = 1000;
    const auto h = ToLcm(s);
    EXPECT_EQ(h.header_kind, pitmap::novatel_header_t::KIND_SHORT_BINARY);
    EXPECT_EQ(h.port, -1);
    EXPECT_EQ(h.sequence, -1);
    EXPECT_EQ(h.idle_percent, -1.0f);
    EXPECT_EQ(h.time_status, -1);
    EXPECT_EQ(h.receiver_status, -1);
    EXPECT_EQ(h.reserved, -1);
    EXPECT_EQ(h.sw_build, -1);
    EXPECT_EQ(h.gps_week, 2300);
    EXPECT_EQ(h.gps_ms, 1000);
    s.kind = nv::HeaderKind::kShortAscii;
    EXPECT_EQ(ToLcm(s).header_kind, pitmap::novatel_header_t::KIND_SHORT_ASCII);
    s.kind = nv::HeaderKind::kAbbreviated;
    EXPECT_EQ(ToLcm(s).gps_week, -1);
}

TEST(ToLcmTest, BestPos) {
    nv::BestPos m;
    m.header = LongHeader(42);
    m.solution_status = nv::SolutionStatus::kSolComputed;
    m.position_type = nv::PositionType::kNarrowInt;
    m.latitude_deg = 51.116;
    m.longitude_deg = -114.038;
    m.height_msl_m = 1064.5;
    m.undulation_m = -16.27f;
    m.datum_id = 61;
    m.latitude_stddev_m = 0.01f;
    m.longitude_stddev_m = 0.02f;
    m.height_stddev_m = 0.03f;
    m.base_station_id = "AAAA";
    m.differential_age_s = 1.5f;
    m.solution_age_s = 0.25f;
    m.num_svs_tracked = 20;
    m.num_svs_in_solution = 18;
    m.num_svs_l1_in_solution = 17;
    m.num_svs_multifreq_in_solution = 16;
    m.extended_solution_status = 0x21;
    m.galileo_beidou_signal_mask = 0x30;
    m.gps_glonass_signal_mask = 0x33;
    const auto o = RoundTrip(ToLcm(m, kHost));
    EXPECT_EQ(o.utime, kHost);
    EXPECT_EQ(o.utime_gps, kHeaderGps);
    EXPECT_EQ(o.header.message_id, 42);
    EXPECT_EQ(o.solution_status, 0);
    EXPECT_EQ(o.position_type, 50);
    EXPECT_DOUBLE_EQ(o.latitude_deg, 51.116);
    EXPECT_DOUBLE_EQ(o.longitude_deg, -114.038);
    EXPECT_DOUBLE_EQ(o.height_msl_m, 1064.5);
    EXPECT_FLOAT_EQ(o.undulation_m, -16.27f);
    EXPECT_EQ(o.datum_id, 61);
    EXPECT_FLOAT_EQ(o.latitude_stddev_m, 0.01f);
    EXPECT_FLOAT_EQ(o.longitude_stddev_m, 0.02f);
    EXPECT_FLOAT_EQ(o.height_stddev_m, 0.03f);
    EXPECT_EQ(o.base_station_id, "AAAA");
    EXPECT_FLOAT_EQ(o.differential_age_s, 1.5f);
    EXPECT_FLOAT_EQ(o.solution_age_s, 0.25f);
    EXPECT_EQ(o.num_svs_tracked, 20);
    EXPECT_EQ(o.num_svs_in_solution, 18);
    EXPECT_EQ(o.num_svs_l1_in_solution, 17);
    EXPECT_EQ(o.num_svs_multifreq_in_solution, 16);
    EXPECT_EQ(o.extended_solution_status, 0x21);
    EXPECT_EQ(o.galileo_beidou_signal_mask, 0x30);
    EXPECT_EQ(o.gps_glonass_signal_mask, 0x33);
}

TEST(ToLcmTest, BestVelUsesHeaderTimeMinusLatency) {
    nv::BestVel m;
    m.header = LongHeader(99);
    m.solution_status = nv::SolutionStatus::kInsufficientObs;
    m.velocity_type = nv::PositionType::kDopplerVelocity;
    m.latency_s = 0.25f;
    m.differential_age_s = 2.0f;
    m.horizontal_speed_mps = 1.75;
    m.track_over_ground_deg = 271.5;
    m.vertical_speed_mps = -0.125;
    const auto o = RoundTrip(ToLcm(m, kHost));
    EXPECT_EQ(o.utime, kHost);
    EXPECT_EQ(o.utime_gps, kHeaderGps - 250'000);
    EXPECT_EQ(o.solution_status, 1);
    EXPECT_EQ(o.velocity_type, 8);
    EXPECT_FLOAT_EQ(o.latency_s, 0.25f);
    EXPECT_FLOAT_EQ(o.differential_age_s, 2.0f);
    EXPECT_DOUBLE_EQ(o.horizontal_speed_mps, 1.75);
    EXPECT_DOUBLE_EQ(o.track_over_ground_deg, 271.5);
    EXPECT_DOUBLE_EQ(o.vertical_speed_mps, -0.125);
}

TEST(ToLcmTest, InsPvaHasNoStddevAndUsesBodyTime) {
    nv::InsPva m;
    m.header = LongHeader(508);
    m.header.kind = nv::HeaderKind::kShortBinary;
    m.gps_week = 2300;
    m.gps_seconds = 345678.905;
    m.latitude_deg = 41.1;
    m.longitude_deg = -8.6;
    m.height_ellipsoid_m = 60.5;
    m.velocity_north_mps = 1.0;
    m.velocity_east_mps = 2.0;
    m.velocity_up_mps = -0.5;
    m.roll_deg = 1.5;
    m.pitch_deg = -2.5;
    m.azimuth_deg = 359.5;
    m.ins_status = nv::InsStatus::kSolutionGood;
    const auto o = RoundTrip(ToLcm(m, kHost));
    EXPECT_EQ(o.utime, kHost);
    EXPECT_EQ(o.utime_gps, GpsUtimeFromWeekTow(2300, 345678.905));
    EXPECT_EQ(o.header.header_kind, pitmap::novatel_header_t::KIND_SHORT_BINARY);
    EXPECT_EQ(o.ins_status, 3);
    EXPECT_EQ(o.position_type, -1);
    EXPECT_DOUBLE_EQ(o.latitude_deg, 41.1);
    EXPECT_DOUBLE_EQ(o.longitude_deg, -8.6);
    EXPECT_DOUBLE_EQ(o.height_ellipsoid_m, 60.5);
    EXPECT_TRUE(std::isnan(o.undulation_m));
    EXPECT_DOUBLE_EQ(o.velocity_north_mps, 1.0);
    EXPECT_DOUBLE_EQ(o.velocity_east_mps, 2.0);
    EXPECT_DOUBLE_EQ(o.velocity_up_mps, -0.5);
    EXPECT_DOUBLE_EQ(o.roll_deg, 1.5);
    EXPECT_DOUBLE_EQ(o.pitch_deg, -2.5);
    EXPECT_DOUBLE_EQ(o.azimuth_deg, 359.5);
    EXPECT_EQ(o.has_stddev, 0);
    for (float f : {o.latitude_stddev_m,
                    o.longitude_stddev_m,
                    o.height_stddev_m,
                    o.velocity_north_stddev_mps,
                    o.velocity_east_stddev_mps,
                    o.velocity_up_stddev_mps,
                    o.roll_stddev_deg,
                    o.pitch_stddev_deg,
                    o.azimuth_stddev_deg}) {
        EXPECT_TRUE(std::isnan(f));
    }
    EXPECT_EQ(o.extended_status, -1);
    EXPECT_EQ(o.time_since_update_s, -1);
}

TEST(ToLcmTest, InsPvaXAddsUndulationToHeight) {
    nv::InsPvaX m;
    m.header = LongHeader(1465);
    m.ins_status = nv::InsStatus::kSolutionGood;
    m.position_type = nv::PositionType::kInsRtkFixed;
    m.latitude_deg = 41.1;
    m.longitude_deg = -8.6;
    m.height_msl_m = 10.0;
    m.undulation_m = 50.5f;
    m.velocity_north_mps = 0.1;
    m.velocity_east_mps = 0.2;
    m.velocity_up_mps = 0.3;
    m.roll_deg = 0.4;
    m.pitch_deg = 0.5;
    m.azimuth_deg = 0.6;
    m.latitude_stddev_m = 1.0f;
    m.longitude_stddev_m = 2.0f;
    m.height_stddev_m = 3.0f;
    m.velocity_north_stddev_mps = 4.0f;
    m.velocity_east_stddev_mps = 5.0f;
    m.velocity_up_stddev_mps = 6.0f;
    m.roll_stddev_deg = 7.0f;
    m.pitch_stddev_deg = 8.0f;
    m.azimuth_stddev_deg = 9.0f;
    m.extended_status = 0x1234;
    m.time_since_update_s = 12;
    const auto o = RoundTrip(ToLcm(m, kHost));
    EXPECT_EQ(o.utime_gps, kHeaderGps);
    EXPECT_EQ(o.ins_status, 3);
    EXPECT_EQ(o.position_type, 56);
    EXPECT_DOUBLE_EQ(o.height_ellipsoid_m, 60.5);
    EXPECT_FLOAT_EQ(o.undulation_m, 50.5f);
    EXPECT_DOUBLE_EQ(o.velocity_north_mps, 0.1);
    EXPECT_DOUBLE_EQ(o.velocity_east_mps, 0.2);
    EXPECT_DOUBLE_EQ(o.velocity_up_mps, 0.3);
    EXPECT_DOUBLE_EQ(o.roll_deg, 0.4);
    EXPECT_DOUBLE_EQ(o.pitch_deg, 0.5);
    EXPECT_DOUBLE_EQ(o.azimuth_deg, 0.6);
    EXPECT_EQ(o.has_stddev, 1);
    EXPECT_FLOAT_EQ(o.latitude_stddev_m, 1.0f);
    EXPECT_FLOAT_EQ(o.longitude_stddev_m, 2.0f);
    EXPECT_FLOAT_EQ(o.height_stddev_m, 3.0f);
    EXPECT_FLOAT_EQ(o.velocity_north_stddev_mps, 4.0f);
    EXPECT_FLOAT_EQ(o.velocity_east_stddev_mps, 5.0f);
    EXPECT_FLOAT_EQ(o.velocity_up_stddev_mps, 6.0f);
    EXPECT_FLOAT_EQ(o.roll_stddev_deg, 7.0f);
    EXPECT_FLOAT_EQ(o.pitch_stddev_deg, 8.0f);
    EXPECT_FLOAT_EQ(o.azimuth_stddev_deg, 9.0f);
    EXPECT_EQ(o.extended_status, 0x1234);
    EXPECT_EQ(o.time_since_update_s, 12);
}

TEST(ToLcmTest, InsAttAndInsAttX) {
    nv::InsAtt a;
    a.header = LongHeader(263);
    a.gps_week = 2300;
    a.gps_seconds = 100.5;
    a.roll_deg = 1.0;
    a.pitch_deg = 2.0;
    a.azimuth_deg = 3.0;
    a.ins_status = nv::InsStatus::kAligning;
    const auto o = RoundTrip(ToLcm(a, kHost));
    EXPECT_EQ(o.utime, kHost);
    EXPECT_EQ(o.utime_gps, GpsUtimeFromWeekTow(2300, 100.5));
    EXPECT_EQ(o.ins_status, 1);
    EXPECT_EQ(o.position_type, -1);
    EXPECT_DOUBLE_EQ(o.roll_deg, 1.0);
    EXPECT_DOUBLE_EQ(o.pitch_deg, 2.0);
    EXPECT_DOUBLE_EQ(o.azimuth_deg, 3.0);
    EXPECT_EQ(o.has_stddev, 0);
    EXPECT_TRUE(std::isnan(o.roll_stddev_deg));
    EXPECT_TRUE(std::isnan(o.pitch_stddev_deg));
    EXPECT_TRUE(std::isnan(o.azimuth_stddev_deg));
    EXPECT_EQ(o.extended_status, -1);
    EXPECT_EQ(o.time_since_update_s, -1);

    nv::InsAttX x;
    x.header = LongHeader(1457);
    x.ins_status = nv::InsStatus::kSolutionGood;
    x.position_type = nv::PositionType::kInsPpp;
    x.roll_deg = 4.0;
    x.pitch_deg = 5.0;
    x.azimuth_deg = 6.0;
    x.roll_stddev_deg = 0.1f;
    x.pitch_stddev_deg = 0.2f;
    x.azimuth_stddev_deg = 0.3f;
    x.extended_status = 77;
    x.time_since_update_s = 3;
    const auto ox = RoundTrip(ToLcm(x, kHost));
    EXPECT_EQ(ox.utime_gps, kHeaderGps);
    EXPECT_EQ(ox.position_type, 74);
    EXPECT_DOUBLE_EQ(ox.roll_deg, 4.0);
    EXPECT_DOUBLE_EQ(ox.pitch_deg, 5.0);
    EXPECT_DOUBLE_EQ(ox.azimuth_deg, 6.0);
    EXPECT_EQ(ox.has_stddev, 1);
    EXPECT_FLOAT_EQ(ox.roll_stddev_deg, 0.1f);
    EXPECT_FLOAT_EQ(ox.pitch_stddev_deg, 0.2f);
    EXPECT_FLOAT_EQ(ox.azimuth_stddev_deg, 0.3f);
    EXPECT_EQ(ox.extended_status, 77);
    EXPECT_EQ(ox.time_since_update_s, 3);
}

TEST(ToLcmTest, InsStdDev) {
    nv::InsStdDev m;
    m.header = LongHeader(2051);
    m.latitude_stddev_m = 1.0f;
    m.longitude_stddev_m = 2.0f;
    m.height_stddev_m = 3.0f;
    m.velocity_north_stddev_mps = 4.0f;
    m.velocity_east_stddev_mps = 5.0f;
    m.velocity_up_stddev_mps = 6.0f;
    m.roll_stddev_deg = 7.0f;
    m.pitch_stddev_deg = 8.0f;
    m.azimuth_stddev_deg = 9.0f;
    m.extended_status = 10;
    m.time_since_update_s = 11;
    const auto o = RoundTrip(ToLcm(m, kHost));
    EXPECT_EQ(o.utime, kHost);
    EXPECT_EQ(o.utime_gps, kHeaderGps);
    EXPECT_FLOAT_EQ(o.latitude_stddev_m, 1.0f);
    EXPECT_FLOAT_EQ(o.longitude_stddev_m, 2.0f);
    EXPECT_FLOAT_EQ(o.height_stddev_m, 3.0f);
    EXPECT_FLOAT_EQ(o.velocity_north_stddev_mps, 4.0f);
    EXPECT_FLOAT_EQ(o.velocity_east_stddev_mps, 5.0f);
    EXPECT_FLOAT_EQ(o.velocity_up_stddev_mps, 6.0f);
    EXPECT_FLOAT_EQ(o.roll_stddev_deg, 7.0f);
    EXPECT_FLOAT_EQ(o.pitch_stddev_deg, 8.0f);
    EXPECT_FLOAT_EQ(o.azimuth_stddev_deg, 9.0f);
    EXPECT_EQ(o.extended_status, 10);
    EXPECT_EQ(o.time_since_update_s, 11);
}

TEST(ToLcmTest, CorrImuDataRatesFromTheGivenRate) {
    nv::CorrImuData m;
    m.header = LongHeader(813);
    m.gps_week = 2300;
    m.gps_seconds = 10.0;
    m.delta_angle_rad = {0.001, -0.002, 0.003};
    m.delta_velocity_mps = {0.01, 0.02, -0.03};
    const auto o = RoundTrip(ToLcm(m, kHost, 200.0));
    EXPECT_EQ(o.utime_gps, GpsUtimeFromWeekTow(2300, 10.0));
    EXPECT_EQ(o.frame, pitmap::imu_t::FRAME_VEHICLE_RFU);
    EXPECT_EQ(o.corrected, 1);
    EXPECT_EQ(o.imu_type, -1);
    EXPECT_EQ(o.imu_status, -1);
    EXPECT_EQ(o.sample_count, 1);
    EXPECT_DOUBLE_EQ(o.dt_s, 0.005);
    for (int i = 0; i < 3; ++i) {
        EXPECT_DOUBLE_EQ(o.delta_angle_rad[i], m.delta_angle_rad[i]);
        EXPECT_DOUBLE_EQ(o.delta_velocity_mps[i], m.delta_velocity_mps[i]);
        EXPECT_DOUBLE_EQ(o.angular_rate_radps[i], m.delta_angle_rad[i] * 200.0);
        EXPECT_DOUBLE_EQ(o.acceleration_mps2[i], m.delta_velocity_mps[i] * 200.0);
    }
    const auto unknown = ToLcm(m, kHost, 0.0);
    EXPECT_TRUE(std::isnan(unknown.dt_s));
    EXPECT_DOUBLE_EQ(unknown.delta_angle_rad[1], -0.002);
    for (int i = 0; i < 3; ++i) {
        EXPECT_TRUE(std::isnan(unknown.angular_rate_radps[i]));
        EXPECT_TRUE(std::isnan(unknown.acceleration_mps2[i]));
    }
}

TEST(ToLcmTest, CorrImuSDividesBySampleCount) {
    nv::CorrImuS m;
    m.header = LongHeader(2264);
    m.header.kind = nv::HeaderKind::kShortBinary;
    m.imu_data_count = 4;
    m.delta_angle_rad = {0.004, 0.008, -0.004};
    m.delta_velocity_mps = {0.04, 0.0, 0.4};
    const auto o = RoundTrip(ToLcm(m, kHost, 200.0));
    EXPECT_EQ(o.sample_count, 4);
    EXPECT_DOUBLE_EQ(o.dt_s, 0.02);
    EXPECT_NEAR(o.angular_rate_radps[0], 0.2, 1e-12);
    EXPECT_NEAR(o.acceleration_mps2[2], 20.0, 1e-12);
    EXPECT_EQ(o.corrected, 1);
    EXPECT_TRUE(std::isnan(ToLcm(m, kHost, 0.0).dt_s));
}

TEST(ToLcmTest, RawImuScaledByTheTable) {
    nv::RawImu m;
    m.header = LongHeader(1462);
    m.imu_type = 13;  // HG1700-AG58 in the §6.9 table
    m.gps_week = 2300;
    m.gps_seconds = 20.0;
    m.imu_status = 0x77;
    m.accel_counts = {100, -200, 300};
    m.gyro_counts = {-10, 20, -30};
    const auto scale = nv::ImuScaleFor(13, 100.0);
    ASSERT_TRUE(scale.has_value());
    const auto o = RoundTrip(ToLcm(m, kHost, 100.0));
    EXPECT_EQ(o.frame, pitmap::imu_t::FRAME_IMU_BODY);
    EXPECT_EQ(o.corrected, 0);
    EXPECT_EQ(o.imu_type, 13);
    EXPECT_EQ(o.imu_status, 0x77);
    EXPECT_EQ(o.sample_count, 1);
    EXPECT_DOUBLE_EQ(o.dt_s, 0.01);
    EXPECT_EQ(o.utime_gps, GpsUtimeFromWeekTow(2300, 20.0));
    for (int i = 0; i < 3; ++i) {
        EXPECT_DOUBLE_EQ(o.delta_angle_rad[i], m.gyro_counts[i] * scale->gyro_rad_per_count);
        EXPECT_DOUBLE_EQ(o.delta_velocity_mps[i], m.accel_counts[i] * scale->accel_mps_per_count);
        EXPECT_DOUBLE_EQ(o.angular_rate_radps[i], o.delta_angle_rad[i] * 100.0);
        EXPECT_DOUBLE_EQ(o.acceleration_mps2[i], o.delta_velocity_mps[i] * 100.0);
    }
    // RAWIMUS carries no type: the caller's type (INSCONFIG) is used, rate from the table.
    m.imu_type = -1;
    const auto nominal = ToLcm(m, kHost, 0.0, 13);
    EXPECT_EQ(nominal.imu_type, 13);
    EXPECT_DOUBLE_EQ(nominal.dt_s, 1.0 / nv::ImuScaleFor(13)->nominal_rate_hz);
    // Unknown type: nothing scaled, the counts stay in the raw channel.
    const auto unknown = ToLcm(m, kHost, 100.0);
    EXPECT_EQ(unknown.imu_type, -1);
    EXPECT_TRUE(std::isnan(unknown.dt_s));
    for (int i = 0; i < 3; ++i) {
        EXPECT_TRUE(std::isnan(unknown.delta_angle_rad[i]));
        EXPECT_TRUE(std::isnan(unknown.delta_velocity_mps[i]));
        EXPECT_TRUE(std::isnan(unknown.angular_rate_radps[i]));
        EXPECT_TRUE(std::isnan(unknown.acceleration_mps2[i]));
    }
}

TEST(ToLcmTest, Time) {
    nv::Time m;
    m.header = LongHeader(101);
    m.clock_model_status = nv::ClockModelStatus::kConverging;
    m.receiver_clock_offset_s = 1e-8;
    m.receiver_clock_offset_stddev_s = 2e-9;
    m.utc_offset_s = -18.0;
    m.utc_year = 2024;
    m.utc_month = 6;
    m.utc_day = 30;
    m.utc_hour = 23;
    m.utc_minute = 59;
    m.utc_ms = 59'000;
    m.utc_status = nv::UtcStatus::kValid;
    const auto o = RoundTrip(ToLcm(m, kHost));
    EXPECT_EQ(o.utime, kHost);
    EXPECT_EQ(o.utime_gps, kHeaderGps);
    EXPECT_EQ(o.clock_model_status, 1);
    EXPECT_DOUBLE_EQ(o.receiver_clock_offset_s, 1e-8);
    EXPECT_DOUBLE_EQ(o.receiver_clock_offset_stddev_s, 2e-9);
    EXPECT_DOUBLE_EQ(o.utc_offset_s, -18.0);
    EXPECT_EQ(o.utc_year, 2024);
    EXPECT_EQ(o.utc_month, 6);
    EXPECT_EQ(o.utc_day, 30);
    EXPECT_EQ(o.utc_hour, 23);
    EXPECT_EQ(o.utc_minute, 59);
    EXPECT_EQ(o.utc_ms, 59'000);
    EXPECT_EQ(o.utc_status, 1);
}

TEST(ToLcmTest, UnknownTimeStatusGivesZeroGpsTime) {
    nv::Time m;
    m.header = LongHeader(101);
    m.header.time_status = nv::TimeStatus::kUnknown;
    EXPECT_EQ(ToLcm(m, kHost).utime_gps, 0);
}

TEST(ToLcmTest, Heading2) {
    nv::Heading2 m;
    m.header = LongHeader(1335);
    m.solution_status = nv::SolutionStatus::kSolComputed;
    m.position_type = nv::PositionType::kNarrowInt;
    m.baseline_length_m = 1.2f;
    m.heading_deg = 270.5f;
    m.pitch_deg = -1.5f;
    m.heading_stddev_deg = 0.1f;
    m.pitch_stddev_deg = 0.2f;
    m.rover_station_id = "R1";
    m.base_station_id = "B1";
    m.num_svs_tracked = 14;
    m.num_svs_in_solution = 12;
    const auto o = RoundTrip(ToLcm(m, kHost));
    EXPECT_EQ(o.utime_gps, kHeaderGps);
    EXPECT_EQ(o.solution_status, 0);
    EXPECT_EQ(o.position_type, 50);
    EXPECT_FLOAT_EQ(o.baseline_length_m, 1.2f);
    EXPECT_FLOAT_EQ(o.heading_deg, 270.5f);
    EXPECT_FLOAT_EQ(o.pitch_deg, -1.5f);
    EXPECT_FLOAT_EQ(o.heading_stddev_deg, 0.1f);
    EXPECT_FLOAT_EQ(o.pitch_stddev_deg, 0.2f);
    EXPECT_EQ(o.rover_station_id, "R1");
    EXPECT_EQ(o.base_station_id, "B1");
    EXPECT_EQ(o.num_svs_tracked, 14);
    EXPECT_EQ(o.num_svs_in_solution, 12);
}

TEST(ToLcmTest, MarkTimeUsesTheEventTime) {
    nv::MarkTime m;
    m.header = LongHeader(1130);
    m.gps_week = 2300;
    m.gps_seconds = 12345.6789;
    m.clock_offset_s = 1e-9;
    m.clock_offset_stddev_s = 2e-9;
    m.utc_offset_s = -18.0;
    m.clock_model_status = nv::ClockModelStatus::kValid;
    const auto o = RoundTrip(ToLcm(m, kHost));
    EXPECT_EQ(o.utime_gps, m.utime_gps());
    EXPECT_EQ(o.utime_gps, GpsUtimeFromWeekTow(2300, 12345.6789));
    EXPECT_EQ(o.gps_week, 2300);
    EXPECT_DOUBLE_EQ(o.gps_seconds, 12345.6789);
    EXPECT_DOUBLE_EQ(o.clock_offset_s, 1e-9);
    EXPECT_DOUBLE_EQ(o.clock_offset_stddev_s, 2e-9);
    EXPECT_DOUBLE_EQ(o.utc_offset_s, -18.0);
    EXPECT_EQ(o.clock_model_status, 0);
}

TEST(ToLcmTest, ResponsesAbbreviatedAndBinary) {
    nv::Response ok;
    ok.header.kind = nv::HeaderKind::kAbbreviated;
    ok.form = nv::Response::Form::kAbbreviated;
    ok.text = "OK";
    const auto o = RoundTrip(ToLcm(ok, kHost, "novatel_com1", "LOG INSPVAXB ONTIME 0.05"));
    EXPECT_EQ(o.utime, kHost);
    EXPECT_EQ(o.source, "novatel_com1");
    EXPECT_EQ(o.message_id, -1);
    EXPECT_EQ(o.ok, 1);
    EXPECT_EQ(o.response_id, -1);
    EXPECT_EQ(o.text, "OK");
    EXPECT_EQ(o.command, "LOG INSPVAXB ONTIME 0.05");

    nv::Response err;
    err.header = LongHeader(1);
    err.header.is_response = true;
    err.form = nv::Response::Form::kBinary;
    err.response_id = 31;
    err.text = "Message ID is invalid";
    const auto e = ToLcm(err, kHost, "x");
    EXPECT_EQ(e.message_id, 1);
    EXPECT_EQ(e.ok, 0);
    EXPECT_EQ(e.response_id, 31);
    EXPECT_EQ(e.command, "");
}

TEST(ToLcmTest, EncodeNovatelPicksTheConventionChannel) {
    const auto pick = [](const nv::Message& m) {
        const auto e = EncodeNovatel(m, kHost, "nov1", {.imu_type = 13, .imu_rate_hz = 100.0});
        return e ? e->channel : std::string("<none>");
    };
    EXPECT_EQ(pick(nv::BestPos{}), "GNSS_POSITION_NOV1");
    EXPECT_EQ(pick(nv::BestVel{}), "GNSS_VELOCITY_NOV1");
    EXPECT_EQ(pick(nv::InsPva{}), "INS_PVA_NOV1");
    EXPECT_EQ(pick(nv::InsPvaX{}), "INS_PVA_NOV1");
    EXPECT_EQ(pick(nv::InsAtt{}), "INS_ATTITUDE_NOV1");
    EXPECT_EQ(pick(nv::InsAttX{}), "INS_ATTITUDE_NOV1");
    EXPECT_EQ(pick(nv::InsStdDev{}), "INS_STDDEV_NOV1");
    EXPECT_EQ(pick(nv::CorrImuData{}), "IMU_NOV1");
    EXPECT_EQ(pick(nv::CorrImuS{}), "IMU_NOV1");
    EXPECT_EQ(pick(nv::RawImu{}), "IMU_NOV1");
    EXPECT_EQ(pick(nv::Time{}), "GPS_TIME_NOV1");
    EXPECT_EQ(pick(nv::Heading2{}), "HEADING_NOV1");
    EXPECT_EQ(pick(nv::MarkTime{}), "MARK_TIME_NOV1");
    EXPECT_EQ(pick(nv::Response{}), "RESPONSE_NOV1");
    EXPECT_EQ(pick(nv::InsConfig{}), "<none>");
    EXPECT_EQ(pick(nv::RxStatus{}), "<none>");
    EXPECT_EQ(pick(nv::PortPrompt{}), "<none>");

    // The bytes are the encoded ToLcm() of the same message.
    nv::RawImu raw;
    raw.header = LongHeader(325);
    raw.gyro_counts = {1, 2, 3};
    const auto e = EncodeNovatel(raw, kHost, "nov1", {.imu_type = 13, .imu_rate_hz = 100.0});
    ASSERT_TRUE(e.has_value());
    EXPECT_EQ(e->data, EncodeLcm(ToLcm(raw, kHost, 100.0, 13)));
    // IMURATECORRIMUS uses the IMU rate, CORRIMUDATA the log rate.
    nv::CorrImuData c;
    c.header = LongHeader(nv::msg_id::kImuRateCorrImuS);
    const ImuContext ctx{.imu_type = -1, .imu_rate_hz = 200.0, .corrimu_rate_hz = 50.0};
    // LCM 1.3.1's generated decoders type-pun doubles: this needs -fno-strict-aliasing
    // (set PUBLIC on pitmap::acq_daemon), or gcc 12 -O3 returns stale values here.
    const auto dt_of = [&](const nv::CorrImuData& msg) {
        const auto enc = EncodeNovatel(msg, kHost, "n", ctx);
        EXPECT_TRUE(enc.has_value());
        pitmap::imu_t decoded;
        decoded.decode(enc->data.data(), 0, static_cast<int>(enc->data.size()));
        return decoded.dt_s;
    };
    EXPECT_DOUBLE_EQ(dt_of(c), 1.0 / 200.0);
    c.header.message_id = nv::msg_id::kCorrImuData;
    EXPECT_DOUBLE_EQ(dt_of(c), 1.0 / 50.0);
}

dt::Ping83P MakePing(std::uint8_t version, bool intensity) {
    dt::Ping83P p;
    p.format_version = version;
    dt::SetHeaderTime(p, 1'700'000'000'250'000);
    dt::SetHeaderLatitude(p, 41.18);
    dt::SetHeaderLongitude(p, -8.6);
    p.speed_over_ground_knots = 3.4;
    p.course_over_ground_deg = 123.4;
    p.internal_pitch_valid = true;
    p.internal_pitch_deg = 1.5;
    p.internal_roll_valid = false;
    p.internal_heading_valid = true;
    p.internal_heading_deg = 200.0;
    p.samples_per_beam = 500;
    p.sector_size_deg = 120;
    p.start_angle_cdeg = -6000;
    p.angle_increment_cdeg = 25;
    p.acoustic_range_m = 50;
    p.frequency_khz = 260;
    p.sound_velocity_flag = true;
    p.sound_velocity_header_mps = 1480.0;
    p.sound_velocity_mps = 1480.0;
    p.sound_velocity_valid = true;
    p.range_resolution_mm = 10;
    p.pulse_length_us = 55;
    p.profile_tilt_deg = -5.0;
    p.repetition_rate_ms = 100;
    p.ping_number = 4'000'000'000u;
    if (version >= dt::kVersion110) {
        p.sonar_offset_m = {0.5f, -0.25f, 1.0f};
        p.ping_latency_us = 1200;
        p.data_latency_us = 35'000;
        p.sample_rate = 1;
        p.option_flags = 0x05;
        p.pings_averaged = 3;
        p.center_ping_offset_us = 700;
        p.heave_m = 0.1f;
        p.altitude_m = 12.5f;
        p.external_sensor_flags = 0x0F;
        p.external_pitch_deg = 1.0f;
        p.external_roll_deg = 2.0f;
        p.external_heading_deg = 3.0f;
        p.transmit_scan_flag = 1;
        p.transmit_scan_angle_deg = 4.5f;
    }
    p.range_counts = {0, 1000, 65535, 42};
    if (intensity) {
        p.intensity_included = true;
        p.intensities = {1, 2, 3, 65535};
    }
    return p;
}

TEST(ToLcmTest, Ping83PVersion110WithIntensities) {
    // Decode an encoded record so the struct is what the daemon really sees.
    const auto bytes = dt::EncodeRecord83P(MakePing(dt::kVersion110, true));
    ASSERT_FALSE(bytes.empty());
    const auto decoded = dt::DecodeRecord83P(ByteSpan(bytes.data(), bytes.size()));
    ASSERT_TRUE(std::holds_alternative<dt::Ping83P>(decoded));
    const auto& p = std::get<dt::Ping83P>(decoded);
    const auto o = RoundTrip(ToLcm(p, kHost, 123'456'789, 2, 0.001f));
    EXPECT_EQ(o.utime, kHost);
    EXPECT_EQ(o.utime_gps, 123'456'789);
    EXPECT_EQ(o.gps_time_source, pitmap::multibeam_ping_t::TIME_SOURCE_HEADER_CLOCK);
    EXPECT_FLOAT_EQ(o.gps_time_stddev_s, 0.001f);
    EXPECT_EQ(o.utime_sonar_header, 1'700'000'000'250'000);
    EXPECT_EQ(o.format_version, 10);
    EXPECT_EQ(o.ping_number, 4'000'000'000LL);
    EXPECT_FLOAT_EQ(o.sound_speed_mps, 1480.0f);
    EXPECT_EQ(o.sound_speed_valid, 1);
    EXPECT_FLOAT_EQ(o.range_resolution_m, 0.01f);
    EXPECT_FLOAT_EQ(o.start_angle_deg, -60.0f);
    EXPECT_FLOAT_EQ(o.angle_increment_deg, 0.25f);
    EXPECT_EQ(o.sector_size_deg, 120);
    EXPECT_EQ(o.acoustic_range_m, 50);
    EXPECT_EQ(o.frequency_khz, 260);
    EXPECT_EQ(o.samples_per_beam, 500);
    EXPECT_EQ(o.profile_tilt_deg, -5);
    EXPECT_EQ(o.repetition_rate_ms, 100);
    EXPECT_EQ(o.pulse_length_us, 55);
    EXPECT_FLOAT_EQ(o.sonar_offset_m[0], 0.5f);
    EXPECT_FLOAT_EQ(o.sonar_offset_m[1], -0.25f);
    EXPECT_FLOAT_EQ(o.sonar_offset_m[2], 1.0f);
    EXPECT_EQ(o.intensity_included, 1);
    EXPECT_EQ(o.ping_latency_us, 1200);
    EXPECT_EQ(o.data_latency_us, 35'000);
    EXPECT_EQ(o.sample_rate_high, 1);
    EXPECT_EQ(o.option_flags, 5);
    EXPECT_EQ(o.pings_averaged, 3);
    EXPECT_EQ(o.center_ping_offset_us, 700);
    EXPECT_EQ(o.internal_attitude_valid, 1 | 4);
    EXPECT_FLOAT_EQ(o.internal_pitch_deg, 1.5f);
    EXPECT_TRUE(std::isnan(o.internal_roll_deg));
    EXPECT_FLOAT_EQ(o.internal_heading_deg, 200.0f);
    EXPECT_EQ(o.external_sensor_flags, 0x0F);
    EXPECT_FLOAT_EQ(o.external_pitch_deg, 1.0f);
    EXPECT_FLOAT_EQ(o.external_roll_deg, 2.0f);
    EXPECT_FLOAT_EQ(o.external_heading_deg, 3.0f);
    EXPECT_FLOAT_EQ(o.heave_m, 0.1f);
    EXPECT_FLOAT_EQ(o.altitude_m, 12.5f);
    EXPECT_EQ(o.transmit_scan_flag, 1);
    EXPECT_FLOAT_EQ(o.transmit_scan_angle_deg, 4.5f);
    EXPECT_NEAR(o.header_latitude_deg, 41.18, 1e-4);
    EXPECT_NEAR(o.header_longitude_deg, -8.6, 1e-4);
    EXPECT_NEAR(o.speed_over_ground_knots, 3.4f, 1e-5);
    EXPECT_NEAR(o.course_over_ground_deg, 123.4f, 1e-4);
    ASSERT_EQ(o.num_beams, 4);
    EXPECT_EQ(o.range_counts, (std::vector<std::int32_t>{0, 1000, 65535, 42}));
    ASSERT_EQ(o.num_intensities, 4);
    EXPECT_EQ(o.intensities, (std::vector<std::int32_t>{1, 2, 3, 65535}));
}

TEST(ToLcmTest, Ping83PVersion100HasNoLatenciesNorIntensities) {
    const auto bytes = dt::EncodeRecord83P(MakePing(dt::kVersion100, false));
    const auto decoded = dt::DecodeRecord83P(ByteSpan(bytes.data(), bytes.size()));
    ASSERT_TRUE(std::holds_alternative<dt::Ping83P>(decoded));
    const auto o = RoundTrip(ToLcm(std::get<dt::Ping83P>(decoded),
                                   kHost,
                                   0,
                                   pitmap::multibeam_ping_t::TIME_SOURCE_NONE,
                                   std::numeric_limits<float>::quiet_NaN()));
    EXPECT_EQ(o.utime_gps, 0);
    EXPECT_EQ(o.gps_time_source, 0);
    EXPECT_TRUE(std::isnan(o.gps_time_stddev_s));
    EXPECT_EQ(o.format_version, 0);
    EXPECT_EQ(o.ping_latency_us, -1);
    EXPECT_EQ(o.data_latency_us, -1);
    EXPECT_EQ(o.intensity_included, 0);
    EXPECT_EQ(o.num_intensities, 0);
    EXPECT_EQ(o.num_beams, 4);
    EXPECT_EQ(o.sonar_offset_m[0], 0.0f);
    // v1.00 carries hundredths: .25 s survives.
    EXPECT_EQ(o.utime_sonar_header, 1'700'000'000'250'000);
}

TEST(ToLcmTest, PingWithBlankClockAndPosition) {
    dt::Ping83P p = MakePing(dt::kVersion110, false);
    p.header_time_valid = false;
    p.utime_sonar_header = 0;
    p.latitude_deg = std::numeric_limits<double>::quiet_NaN();
    const auto o = ToLcm(p, kHost, 0, 1, 0.02f);
    EXPECT_EQ(o.utime_sonar_header, 0);
    EXPECT_TRUE(std::isnan(o.header_latitude_deg));
}

TEST(ToLcmTest, RawBytesKeepTheDataUnmodified) {
    std::vector<std::byte> data;
    for (int i = 0; i < 256; ++i) data.push_back(static_cast<std::byte>(i));
    const auto o = RoundTrip(MakeRawBytes(kHost,
                                          "novatel_com1",
                                          kProtocolNovatel,
                                          Transport::kSerial,
                                          17,
                                          std::span(data),
                                          {.utime_gps = 99,
                                           .gps_time_valid = true,
                                           .peer = "/dev/ttyUSB0",
                                           .utime_kernel = kHost - 5}));
    EXPECT_EQ(o.utime, kHost);
    EXPECT_EQ(o.utime_gps, 99);
    EXPECT_EQ(o.gps_time_valid, 1);
    EXPECT_EQ(o.source, "novatel_com1");
    EXPECT_EQ(o.protocol, "novatel");
    EXPECT_EQ(o.transport, pitmap::raw_bytes_t::TRANSPORT_SERIAL);
    EXPECT_EQ(o.seq, 17);
    EXPECT_EQ(o.peer, "/dev/ttyUSB0");
    EXPECT_EQ(o.utime_kernel, kHost - 5);
    ASSERT_EQ(o.num_bytes, 256);
    EXPECT_EQ(std::memcmp(o.data.data(), data.data(), 256), 0);

    const std::vector<std::uint8_t> u8 = {1, 2, 3};
    const auto d = MakeRawBytes(
        kHost, "d", kProtocolDeltat83P, Transport::kUdp, 0, std::span<const std::uint8_t>(u8));
    EXPECT_EQ(d.utime_gps, 0);
    EXPECT_EQ(d.gps_time_valid, 0);
    EXPECT_EQ(d.peer, "");
    EXPECT_EQ(d.utime_kernel, 0);
    EXPECT_EQ(d.transport, pitmap::raw_bytes_t::TRANSPORT_UDP);
    EXPECT_EQ(d.data, u8);
}

}  // namespace
}  // namespace pitmap::acq
