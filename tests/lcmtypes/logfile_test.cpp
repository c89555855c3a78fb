// SPDX-License-Identifier: MIT
// Every pitmap lcmtype survives encode -> lcm::LogFile -> decode, and lcm-logplayer replays a
// log written by the project into another log (file:// provider: no network needed).
#include <gtest/gtest.h>
#include <unistd.h>
#include <lcm/lcm-cpp.hpp>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "pitmap/clock_sync_t.hpp"
#include "pitmap/daemon_status_t.hpp"
#include "pitmap/gnss_position_t.hpp"
#include "pitmap/gnss_velocity_t.hpp"
#include "pitmap/gps_time_t.hpp"
#include "pitmap/heading_t.hpp"
#include "pitmap/imu_t.hpp"
#include "pitmap/ins_attitude_t.hpp"
#include "pitmap/ins_pva_t.hpp"
#include "pitmap/ins_stddev_t.hpp"
#include "pitmap/mark_time_t.hpp"
#include "pitmap/multibeam_ping_t.hpp"
#include "pitmap/raw_bytes_t.hpp"
#include "pitmap/receiver_response_t.hpp"

namespace {

template <typename Msg>
std::vector<std::uint8_t> Encode(const Msg& m) {
    std::vector<std::uint8_t> buf(static_cast<std::size_t>(m.getEncodedSize()));
    EXPECT_EQ(m.encode(buf.data(), 0, static_cast<int>(buf.size())), static_cast<int>(buf.size()));
    return buf;
}

template <typename Msg>
Msg Decode(const lcm::LogEvent* ev) {
    Msg m;
    EXPECT_EQ(m.decode(ev->data, 0, ev->datalen), ev->datalen);
    return m;
}

void WriteEvent(lcm::LogFile& log,
                std::int64_t utime,
                const std::string& channel,
                const std::vector<std::uint8_t>& data) {
    lcm::LogEvent ev{};
    ev.timestamp = utime;
    ev.channel = channel;
    ev.datalen = static_cast<int32_t>(data.size());
    ev.data = const_cast<std::uint8_t*>(data.data());
    ASSERT_EQ(log.writeEvent(&ev), 0);
}

pitmap::novatel_header_t Header(int id) {
    pitmap::novatel_header_t h{};
    h.message_id = id;
    h.header_kind = pitmap::novatel_header_t::KIND_LONG_BINARY;
    h.port = 0x20;
    h.time_status = 180;
    h.gps_week = 2070;
    h.gps_ms = 241084000;
    h.receiver_status = 0x02000020;
    h.sw_build = 16809;
    return h;
}

class LcmTypesLog : public ::testing::Test {
protected:
    // One file pair per test and process: ctest runs these tests as separate processes at the
    // same time, and one test's TearDown must not remove the log another is replaying.
    static std::string TestPath(const char* what) {
        return ::testing::TempDir() + "/pitmap_lcmtypes_" +
               ::testing::UnitTest::GetInstance()->current_test_info()->name() + "_" +
               std::to_string(::getpid()) + "_" + what + ".lcmlog";
    }
    std::string path_ = TestPath("test");
    std::string replay_ = TestPath("replay");
    void TearDown() override {
        std::remove(path_.c_str());
        std::remove(replay_.c_str());
    }
};

TEST_F(LcmTypesLog, EveryTypeRoundTrips) {
    pitmap::raw_bytes_t raw{};
    raw.utime = 1'600'000'000'000'000;
    raw.utime_gps = 1'284'000'000'000'000;
    raw.gps_time_valid = 1;
    raw.source = "novatel_com1";
    raw.transport = pitmap::raw_bytes_t::TRANSPORT_SERIAL;
    raw.seq = 7;
    raw.peer = "/dev/ttyUSB0";
    raw.data = {0xAA, 0x44, 0x12, 0x1C, 0x00, 0xFF};
    raw.num_bytes = static_cast<int32_t>(raw.data.size());

    pitmap::ins_pva_t pva{};
    pva.utime = raw.utime + 10;
    pva.header = Header(1465);
    pva.latitude_deg = 40.44;
    pva.longitude_deg = -7.78;
    pva.height_ellipsoid_m = 402.5;
    pva.azimuth_deg = 359.5;
    pva.has_stddev = 1;
    pva.roll_stddev_deg = 0.01f;
    pva.undulation_m = NAN;

    pitmap::multibeam_ping_t ping{};
    ping.utime = raw.utime + 20;
    ping.utime_gps = raw.utime_gps + 20;
    ping.gps_time_source = pitmap::multibeam_ping_t::TIME_SOURCE_HEADER_CLOCK;
    ping.format_version = 10;
    ping.ping_number = 4'000'000'000LL;  // a uint32 beyond int32 range survives
    ping.range_resolution_m = 0.002f;
    ping.start_angle_deg = -60.0f;
    ping.angle_increment_deg = 0.25f;
    ping.num_beams = 480;
    ping.range_counts.assign(480, 0);
    for (int i = 0; i < 480; ++i) ping.range_counts[static_cast<std::size_t>(i)] = 65535 - i;
    ping.intensity_included = 1;
    ping.num_intensities = 480;
    ping.intensities.assign(480, 17);

    pitmap::daemon_status_t status{};
    status.utime = raw.utime + 30;
    status.hostname = "roaz";
    status.num_channels = 2;
    status.channels.resize(2);
    status.channels[0].name = "novatel_com1";
    status.channels[0].num_frame_kinds = 2;
    status.channels[0].frame_kind = {"INSPVAS", "BESTPOS"};
    status.channels[0].frame_count = {1000, 20};
    status.channels[1].name = "deltat_udp";
    status.host_clock.state = pitmap::clock_sync_t::STATE_LOCKED;
    status.host_clock.drift_ppm = -3.5;

    pitmap::gnss_position_t pos{};
    pos.header = Header(42);
    pos.base_station_id = "0";
    pitmap::gnss_velocity_t vel{};
    vel.header = Header(99);
    pitmap::ins_attitude_t att{};
    att.header = Header(319);
    pitmap::ins_stddev_t sd{};
    sd.header = Header(2051);
    pitmap::imu_t imu{};
    imu.header = Header(1462);
    imu.delta_angle_rad[2] = 1e-5;
    pitmap::gps_time_t tm{};
    tm.header = Header(101);
    tm.utc_offset_s = -18.0;
    pitmap::heading_t hd{};
    hd.header = Header(1335);
    pitmap::mark_time_t mk{};
    mk.header = Header(1130);
    pitmap::receiver_response_t resp{};
    resp.text = "ERROR:Invalid Message. Field = 1";
    resp.ok = 0;

    {
        lcm::LogFile log(path_, "w");
        ASSERT_TRUE(log.good());
        WriteEvent(log, raw.utime, "NOVATEL_RAW", Encode(raw));
        WriteEvent(log, pva.utime, "INS_PVA", Encode(pva));
        WriteEvent(log, ping.utime, "MULTIBEAM_PING", Encode(ping));
        WriteEvent(log, status.utime, "DAEMON_STATUS", Encode(status));
        WriteEvent(log, status.utime + 1, "GNSS_POSITION", Encode(pos));
        WriteEvent(log, status.utime + 2, "GNSS_VELOCITY", Encode(vel));
        WriteEvent(log, status.utime + 3, "INS_ATTITUDE", Encode(att));
        WriteEvent(log, status.utime + 4, "INS_STDDEV", Encode(sd));
        WriteEvent(log, status.utime + 5, "IMU", Encode(imu));
        WriteEvent(log, status.utime + 6, "GPS_TIME", Encode(tm));
        WriteEvent(log, status.utime + 7, "HEADING", Encode(hd));
        WriteEvent(log, status.utime + 8, "MARK_TIME", Encode(mk));
        WriteEvent(log, status.utime + 9, "NOVATEL_RESPONSE", Encode(resp));
    }

    lcm::LogFile log(path_, "r");
    ASSERT_TRUE(log.good());
    const lcm::LogEvent* ev = log.readNextEvent();
    ASSERT_NE(ev, nullptr);
    EXPECT_EQ(ev->channel, "NOVATEL_RAW");
    const auto raw2 = Decode<pitmap::raw_bytes_t>(ev);
    EXPECT_EQ(raw2.data, raw.data);
    EXPECT_EQ(raw2.source, raw.source);
    EXPECT_EQ(raw2.seq, 7);

    ev = log.readNextEvent();
    ASSERT_NE(ev, nullptr);
    const auto pva2 = Decode<pitmap::ins_pva_t>(ev);
    EXPECT_EQ(pva2.header.message_id, 1465);
    EXPECT_EQ(pva2.header.gps_week, 2070);
    EXPECT_DOUBLE_EQ(pva2.latitude_deg, 40.44);
    EXPECT_TRUE(std::isnan(pva2.undulation_m));
    EXPECT_FLOAT_EQ(pva2.roll_stddev_deg, 0.01f);

    ev = log.readNextEvent();
    ASSERT_NE(ev, nullptr);
    const auto ping2 = Decode<pitmap::multibeam_ping_t>(ev);
    EXPECT_EQ(ping2.ping_number, 4'000'000'000LL);
    EXPECT_EQ(ping2.range_counts, ping.range_counts);
    EXPECT_EQ(ping2.intensities, ping.intensities);
    EXPECT_EQ(ping2.gps_time_source, pitmap::multibeam_ping_t::TIME_SOURCE_HEADER_CLOCK);

    ev = log.readNextEvent();
    ASSERT_NE(ev, nullptr);
    const auto status2 = Decode<pitmap::daemon_status_t>(ev);
    ASSERT_EQ(status2.channels.size(), 2u);
    EXPECT_EQ(status2.channels[0].frame_count[0], 1000);
    EXPECT_EQ(status2.channels[1].name, "deltat_udp");
    EXPECT_DOUBLE_EQ(status2.host_clock.drift_ppm, -3.5);

    int rest = 0;
    while ((ev = log.readNextEvent()) != nullptr) ++rest;
    EXPECT_EQ(rest, 9);
}

TEST_F(LcmTypesLog, DecodeRejectsTruncatedPayload) {
    pitmap::multibeam_ping_t ping{};
    ping.num_beams = 10;
    ping.range_counts.assign(10, 5);
    const auto buf = Encode(ping);
    pitmap::multibeam_ping_t out;
    EXPECT_LT(out.decode(buf.data(), 0, static_cast<int>(buf.size()) - 3), 0);
}

TEST_F(LcmTypesLog, LogplayerReplaysAProjectLog) {
    constexpr int kEvents = 50;
    {
        lcm::LogFile log(path_, "w");
        ASSERT_TRUE(log.good());
        for (int i = 0; i < kEvents; ++i) {
            pitmap::raw_bytes_t raw{};
            raw.utime = 1'000'000 + i * 1000;  // 1 kHz: 50 ms of log
            raw.source = "test";
            raw.seq = i;
            raw.data = {static_cast<std::uint8_t>(i), 0x44};
            raw.num_bytes = 2;
            WriteEvent(log, raw.utime, "RAW", Encode(raw));
        }
    }
    const std::string cmd = std::string(PITMAP_LCM_LOGPLAYER) + " -s 10 --lcm-url='file://" +
                            replay_ + "?mode=w' '" + path_ + "' >/dev/null 2>&1";
    ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;

    lcm::LogFile log(replay_, "r");
    ASSERT_TRUE(log.good());
    int n = 0;
    while (const lcm::LogEvent* ev = log.readNextEvent()) {
        EXPECT_EQ(ev->channel, "RAW");
        const auto raw = Decode<pitmap::raw_bytes_t>(ev);
        EXPECT_EQ(raw.seq, n);
        ASSERT_EQ(raw.data.size(), 2u);
        EXPECT_EQ(raw.data[0], static_cast<std::uint8_t>(n));
        ++n;
    }
    EXPECT_EQ(n, kEvents);
}

}  // namespace
