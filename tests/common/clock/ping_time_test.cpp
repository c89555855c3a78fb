// SPDX-License-Identifier: MIT
// The ping stamping rule (common/clock/ping_time.hpp): receive instant and its GPS time from a
// chunk's logged times, what the 83P header gives, and PingStamper against the sonar clock
// model driven by hand with the same inputs.
#include "common/clock/ping_time.hpp"

#include <gtest/gtest.h>

#include <random>

#include "common/gps_time.hpp"
#include "common/protocol/deltat/record83p.hpp"

namespace pitmap::clock {
namespace {

namespace dt = protocol::deltat;

constexpr std::int64_t kUnix0 = 1'700'000'000'000'000;

TEST(ReceiveTimes, KernelTimeWhenKnownElseHostTime) {
    EXPECT_EQ(ReceiveUtimeHost({.utime_host = 1000, .utime_gps = 5000, .utime_kernel = 0}), 1000);
    EXPECT_EQ(ReceiveUtimeHost({.utime_host = 1000, .utime_gps = 5000, .utime_kernel = 700}), 700);
    EXPECT_EQ(ReceiveUtimeGps({.utime_host = 1000, .utime_gps = 5000, .utime_kernel = 0}), 5000);
    EXPECT_EQ(ReceiveUtimeGps({.utime_host = 1000, .utime_gps = 5000, .utime_kernel = 700}), 4700);
    // No GPS time for the chunk: none for the ping either, whatever the kernel says.
    EXPECT_EQ(ReceiveUtimeGps({.utime_host = 1000, .utime_gps = 0, .utime_kernel = 700}), 0);
}

dt::Ping83P Ping(std::uint8_t version, std::int64_t header_unix) {
    dt::Ping83P p;
    p.format_version = version;
    dt::SetHeaderTime(p, header_unix);
    if (version >= dt::kVersion110) {
        p.ping_latency_us = 2'000;
        p.data_latency_us = 12'000;
    }
    return p;
}

TEST(ClockInputs, HeaderClockAndLatenciesByVersion) {
    const PingClockInputs v110 = ClockInputsOf(Ping(dt::kVersion110, kUnix0 + 123'000));
    EXPECT_EQ(v110.utime_header, kUnix0 + 123'000);
    EXPECT_EQ(v110.age_at_send_us, 12'000);
    EXPECT_EQ(v110.transmit_after_us, 2'000);
    // v1.00 has no latencies (the decoder gives -1) and a clock in hundredths.
    const PingClockInputs v100 = ClockInputsOf(Ping(dt::kVersion100, kUnix0 + 120'000));
    EXPECT_EQ(v100.utime_header, kUnix0 + 120'000);
    EXPECT_EQ(v100.age_at_send_us, 0);
    EXPECT_EQ(v100.transmit_after_us, 0);
    dt::Ping83P garbled = Ping(dt::kVersion110, kUnix0);
    garbled.header_time_valid = false;
    EXPECT_EQ(ClockInputsOf(garbled).utime_header, 0);
    dt::Ping83P zero = Ping(dt::kVersion110, kUnix0);
    zero.ping_latency_us = 0;
    zero.data_latency_us = -1;
    EXPECT_EQ(ClockInputsOf(zero).age_at_send_us, 0);
    EXPECT_EQ(ClockInputsOf(zero).transmit_after_us, 0);
}

TEST(PingStamper, NothingWithoutAnyTime) {
    PingStamper s;
    dt::Ping83P p = Ping(dt::kVersion110, kUnix0);
    const PingTime t = s.Stamp(p, 0);
    EXPECT_EQ(t.utime_gps, 0);
    EXPECT_EQ(t.method, SonarStampMethod::kNone);
    EXPECT_EQ(t.state, ClockState::kNoTime);
}

// PingStamper = SonarClockModel fed (header, receive GPS, data latency), plus ping latency.
TEST(PingStamper, IsTheSonarModelPlusPingLatency) {
    PingStamper stamper;
    SonarClockModel model;
    std::mt19937_64 rng(3);
    std::uniform_int_distribution<std::int64_t> delay(0, 20'000);
    const std::int64_t gps_minus_unix = GpsFromUnix(0);
    int header_model = 0;
    for (int i = 0; i < 400; ++i) {
        const std::int64_t header = kUnix0 + i * 100'000 + 7 * i;  // topside clock, drifting
        const dt::Ping83P p = Ping(dt::kVersion110, header);
        const std::int64_t receive_gps = header + gps_minus_unix + 12'000 + delay(rng);
        const PingTime t = stamper.Stamp(p, receive_gps);
        const SonarStamp m = model.Update({.utime_header = p.utime_sonar_header,
                                           .utime_gps_receive = receive_gps,
                                           .age_at_send_us = 12'000});
        ASSERT_NE(m.utime_gps, 0);
        EXPECT_EQ(t.utime_gps, m.utime_gps + 2'000) << i;
        EXPECT_EQ(t.method, m.method);
        EXPECT_EQ(t.state, m.state);
        header_model += t.method == SonarStampMethod::kHeaderModel ? 1 : 0;
    }
    EXPECT_EQ(header_model, 400);
    EXPECT_EQ(stamper.model().Quality(kUnix0 + 40'000'000).state, ClockState::kLocked);
}

}  // namespace
}  // namespace pitmap::clock
