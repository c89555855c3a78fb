// SPDX-License-Identifier: MIT
// Live status and alarms from synthetic decoded messages: each alarm raised with its reason
// and cleared again, the ping rate, and the transitions kept.
#include "processor/live/status.hpp"

#include <gtest/gtest.h>

#include <algorithm>

namespace pitmap::proc::live {
namespace {

constexpr std::int64_t kT0 = 1'781'500'000'000'000;  // host time, Unix microseconds
constexpr std::int64_t kS = 1'000'000;

const Alarm* Find(const StatusTracker& t, const std::string& id) {
    auto it = std::find_if(
        t.alarms().begin(), t.alarms().end(), [&](const Alarm& a) { return a.id == id; });
    return it == t.alarms().end() ? nullptr : &*it;
}

// Feeds pings at 10 Hz and good INS at 50 Hz from t0 to t1 (host time = wall time).
void Healthy(StatusTracker& t, std::int64_t t0, std::int64_t t1) {
    for (std::int64_t u = t0; u <= t1; u += kS / 50) {
        NavStatusIn n;
        n.utime = u;
        n.utime_gps = u;
        n.ins_status = 3;
        n.north_sigma_m = n.east_sigma_m = 0.01f;
        n.heading_sigma_deg = 0.05f;
        t.OnNav(n);
        t.OnMessage("INS_PVA_NOVATEL", u, 200, u);
        if ((u - t0) % (kS / 10) == 0) {
            t.OnPing({u, u, 120});
            t.OnMessage("MULTIBEAM_PING_DELTAT", u, 1000, u);
            GnssStatusIn g;
            g.utime = u;
            g.solution_status = 0;
            g.position_type = 50;
            t.OnGnss(g);
        }
    }
}

TEST(StatusTracker, HealthySurveyHasNoAlarmAndItsPingRate) {
    StatusTracker t(StatusConfig{});
    Healthy(t, kT0, kT0 + 10 * kS);
    t.Evaluate(kT0 + 10 * kS);
    EXPECT_TRUE(t.alarms().empty());
    const StatusSnapshot s = t.Snapshot();
    EXPECT_NEAR(s.ping_rate_hz, 10.0, 0.01);
    EXPECT_EQ(s.pings, 101);
    EXPECT_EQ(s.lcm_channels.at("MULTIBEAM_PING_DELTAT").messages, 101);
    EXPECT_EQ(s.data_utime, kT0 + 10 * kS);
}

TEST(StatusTracker, SonarSilentRaisedThenCleared) {
    StatusTracker t(StatusConfig{});
    Healthy(t, kT0, kT0 + 5 * kS);
    // INS goes on for 4 s without pings.
    for (std::int64_t u = kT0 + 5 * kS; u <= kT0 + 9 * kS; u += kS / 50) {
        NavStatusIn n;
        n.utime = u;
        n.ins_status = 3;
        t.OnNav(n);
        t.OnMessage("INS_PVA_NOVATEL", u, 200, u);
    }
    t.Evaluate(kT0 + 9 * kS);
    const Alarm* a = Find(t, "sonar_silent");
    ASSERT_NE(a, nullptr);
    EXPECT_NE(a->reason.find("no ping for 4.0 s"), std::string::npos) << a->reason;
    Healthy(t, kT0 + 9 * kS, kT0 + 10 * kS);
    t.Evaluate(kT0 + 10 * kS);
    EXPECT_EQ(Find(t, "sonar_silent"), nullptr);
    std::vector<AlarmEvent> h;
    for (const AlarmEvent& e : t.Snapshot().history) {
        if (e.id == "sonar_silent") h.push_back(e);
    }
    ASSERT_EQ(h.size(), 2u);
    EXPECT_TRUE(h[0].raised);
    EXPECT_FALSE(h[1].raised);
    EXPECT_EQ(h[1].utime, kT0 + 10 * kS);
}

TEST(StatusTracker, SonarChannelSilentInTheDaemonStatus) {
    StatusTracker t(StatusConfig{});
    Healthy(t, kT0, kT0 + 2 * kS);
    DaemonStatusIn d;
    d.utime = kT0 + 2 * kS;
    d.disk_free_bytes = 10LL << 30;
    d.logging = 1;
    ChannelStatusIn c;
    c.name = "deltat_udp";
    c.protocol = "deltat_83p";
    c.state = 4;
    d.channels.push_back(c);
    t.OnDaemon(d);
    t.Evaluate(kT0 + 2 * kS);
    const Alarm* a = Find(t, "sonar_silent");
    ASSERT_NE(a, nullptr);
    EXPECT_NE(a->reason.find("deltat_udp disconnected"), std::string::npos) << a->reason;
}

TEST(StatusTracker, InsDegradedByStatusOrSigma) {
    StatusTracker t(StatusConfig{});
    Healthy(t, kT0, kT0 + kS);
    NavStatusIn n;
    n.utime = kT0 + kS;
    n.ins_status = 2;  // INS_HIGH_VARIANCE
    n.north_sigma_m = 0.6f;
    n.east_sigma_m = 0.8f;
    t.OnNav(n);
    t.Evaluate(kT0 + kS);
    const Alarm* a = Find(t, "ins_degraded");
    ASSERT_NE(a, nullptr);
    EXPECT_NE(a->reason.find("HIGH_VARIANCE"), std::string::npos) << a->reason;
    EXPECT_NE(a->reason.find("horizontal sigma 1.00 m"), std::string::npos) << a->reason;
    n.ins_status = 3;
    n.north_sigma_m = n.east_sigma_m = 0.01f;
    n.heading_sigma_deg = 2.0f;
    t.OnNav(n);
    t.Evaluate(kT0 + kS);
    a = Find(t, "ins_degraded");
    ASSERT_NE(a, nullptr);
    EXPECT_NE(a->reason.find("heading sigma 2.00 deg"), std::string::npos) << a->reason;
    n.heading_sigma_deg = 0.05f;
    t.OnNav(n);
    t.Evaluate(kT0 + kS);
    EXPECT_EQ(Find(t, "ins_degraded"), nullptr);
}

TEST(StatusTracker, GnssOutageAfterSilenceOrBadSolution) {
    StatusTracker t(StatusConfig{});
    Healthy(t, kT0, kT0 + 2 * kS);
    // Nav and pings continue, GNSS stops.
    for (std::int64_t u = kT0 + 2 * kS; u <= kT0 + 6 * kS; u += kS / 10) {
        NavStatusIn n;
        n.utime = u;
        n.ins_status = 3;
        t.OnNav(n);
        t.OnPing({u, u, 120});
        t.OnMessage("MULTIBEAM_PING_DELTAT", u, 1000, u);
    }
    t.Evaluate(kT0 + 6 * kS);
    ASSERT_NE(Find(t, "gnss_outage"), nullptr);
    EXPECT_TRUE(t.Snapshot().gnss_outage);
    // A computed solution again clears it; INSUFFICIENT_OBS for long enough raises it again.
    GnssStatusIn g;
    g.utime = kT0 + 6 * kS;
    g.solution_status = 0;
    g.position_type = 50;
    t.OnGnss(g);
    t.Evaluate(kT0 + 6 * kS);
    EXPECT_EQ(Find(t, "gnss_outage"), nullptr);
    for (std::int64_t u = kT0 + 6 * kS; u <= kT0 + 10 * kS; u += kS) {
        g.utime = u;
        g.solution_status = 1;
        t.OnGnss(g);
        t.OnMessage("GNSS_POSITION_NOVATEL", u, 100, u);
    }
    t.Evaluate(kT0 + 10 * kS);
    const Alarm* a = Find(t, "gnss_outage");
    ASSERT_NE(a, nullptr);
    EXPECT_NE(a->reason.find("not computed"), std::string::npos) << a->reason;
}

TEST(StatusTracker, ClockNotLocked) {
    StatusTracker t(StatusConfig{});
    Healthy(t, kT0, kT0 + kS);
    t.OnClock({kT0 + kS, 1, 1, 1000, 350, 2.0});  // host clock converging
    t.OnClock({kT0 + kS, 3, 0, 0, 0, 0});         // sonar header clock unused: no alarm
    t.Evaluate(kT0 + kS);
    const Alarm* a = Find(t, "clock_not_locked");
    ASSERT_NE(a, nullptr);
    EXPECT_NE(a->reason.find("host_from_novatel clock converging"), std::string::npos) << a->reason;
    EXPECT_EQ(a->reason.find("sonar_header"), std::string::npos) << a->reason;
    t.OnClock({kT0 + kS, 1, 2, 1000, 5, 2.0});
    t.Evaluate(kT0 + kS);
    EXPECT_EQ(Find(t, "clock_not_locked"), nullptr);
    t.OnClock({kT0 + kS, 1, 3, 1000, 5, 2.0});  // holdover
    t.Evaluate(kT0 + kS);
    ASSERT_NE(Find(t, "clock_not_locked"), nullptr);
}

TEST(StatusTracker, DiskLowAndDropsRising) {
    StatusConfig cfg;
    cfg.disk_low_bytes = 1'000'000'000;
    cfg.drops_window_s = 10;
    StatusTracker t(cfg);
    Healthy(t, kT0, kT0 + kS);
    DaemonStatusIn d;
    d.logging = 1;
    d.disk_free_bytes = 5'000'000'000;
    ChannelStatusIn c;
    c.name = "novatel_com1";
    c.protocol = "novatel";
    c.state = 2;
    d.channels.push_back(c);
    for (int k = 0; k < 12; ++k) {  // steady drops count for 12 s
        d.utime = kT0 + k * kS;
        t.OnDaemon(d);
        t.OnMessage("DAEMON_STATUS", d.utime, 500, d.utime);
    }
    t.Evaluate(d.utime);
    EXPECT_EQ(Find(t, "drops_rising"), nullptr);
    EXPECT_EQ(Find(t, "disk_low"), nullptr);
    d.utime += kS;
    d.channels[0].queue_drops = 7;
    d.log_events_dropped = 3;
    d.disk_free_bytes = 500'000'000;
    t.OnDaemon(d);
    t.OnMessage("DAEMON_STATUS", d.utime, 500, d.utime);
    t.Evaluate(d.utime);
    const Alarm* drops = Find(t, "drops_rising");
    ASSERT_NE(drops, nullptr);
    EXPECT_NE(drops->reason.find("10 drops"), std::string::npos) << drops->reason;
    const Alarm* disk = Find(t, "disk_low");
    ASSERT_NE(disk, nullptr);
    EXPECT_NE(disk->reason.find("500 MB free"), std::string::npos) << disk->reason;
    // Twelve more seconds without new drops: drops_rising clears; the disk guard trips.
    for (int k = 0; k < 12; ++k) {
        d.utime += kS;
        d.logging = 2;
        t.OnDaemon(d);
        t.OnMessage("DAEMON_STATUS", d.utime, 500, d.utime);
    }
    t.Evaluate(d.utime);
    EXPECT_EQ(Find(t, "drops_rising"), nullptr);
    disk = Find(t, "disk_low");
    ASSERT_NE(disk, nullptr);
    EXPECT_NE(disk->reason.find("disk_guard"), std::string::npos) << disk->reason;
}

TEST(StatusTracker, NoMessagesOnTheWallClock) {
    StatusTracker t(StatusConfig{});
    Healthy(t, kT0, kT0 + kS);
    t.Evaluate(kT0 + kS + 4 * kS);
    EXPECT_EQ(Find(t, "no_messages"), nullptr);
    t.Evaluate(kT0 + kS + 6 * kS);
    const Alarm* a = Find(t, "no_messages");
    ASSERT_NE(a, nullptr);
    EXPECT_NE(a->reason.find("6.0 s"), std::string::npos) << a->reason;
}

// A replay that reached its end: silence is expected, the alarm is cleared and stays off.
TEST(StatusTracker, NoNoMessagesAlarmAfterTheFeedEnded) {
    StatusTracker t(StatusConfig{});
    Healthy(t, kT0, kT0 + kS);
    t.Evaluate(kT0 + kS + 6 * kS);
    ASSERT_NE(Find(t, "no_messages"), nullptr);
    t.SetFeedEnded();
    EXPECT_TRUE(t.feed_ended());
    t.Evaluate(kT0 + kS + 7 * kS);
    EXPECT_EQ(Find(t, "no_messages"), nullptr);
    t.Evaluate(kT0 + kS + 600 * kS);
    EXPECT_EQ(Find(t, "no_messages"), nullptr);
}

TEST(StatusTracker, ImplausibleStampsDoNotMoveTheDataClock) {
    StatusTracker t(StatusConfig{});
    t.OnMessage("X", 5, 10, kT0);  // a stamp near 1970
    EXPECT_EQ(t.Snapshot().data_utime, 0);
    t.OnDecodeFailure("X");
    EXPECT_EQ(t.Snapshot().lcm_channels.at("X").decode_failures, 1);
    t.Evaluate(kT0);
    EXPECT_TRUE(t.alarms().empty());
}

TEST(StatusConfig, Validation) {
    EXPECT_TRUE(StatusConfig{}.Validate().empty());
    StatusConfig c;
    c.sonar_silent_s = 0;
    c.disk_low_bytes = -1;
    EXPECT_EQ(c.Validate().size(), 2u);
}

TEST(StatusTracker, TvuOverLimitOnTheShareOfNewCellsWithinTheWindow) {
    StatusTracker t(StatusConfig{});  // 10 %, 30 s, at least 20 new cells
    Healthy(t, kT0, kT0 + 2 * kS);
    // 15 new cells, all failing: too few for a verdict.
    t.OnTvuCells({kT0 + 1 * kS, 15, 15, "1a"});
    t.Evaluate(kT0 + 2 * kS);
    EXPECT_EQ(Find(t, "tvu_over_limit"), nullptr);
    // 85 more, 5 failing: 20 of 100 = 20 % > 10 %.
    t.OnTvuCells({kT0 + 2 * kS, 85, 5, "1a"});
    t.Evaluate(kT0 + 2 * kS);
    const Alarm* a = Find(t, "tvu_over_limit");
    ASSERT_NE(a, nullptr);
    EXPECT_NE(a->reason.find("TVU over the order 1a limit in 20 % of new cells (20 of 100"),
              std::string::npos)
        << a->reason;
    // 31 s later the first batch has left the window: 5 of 85 = 5.9 %, cleared.
    Healthy(t, kT0 + 2 * kS, kT0 + 31'500'000);
    t.Evaluate(kT0 + 31'500'000);
    EXPECT_EQ(Find(t, "tvu_over_limit"), nullptr);
    // Exactly at the threshold is not over it: 2 of 20 = 10 %.
    StatusTracker u(StatusConfig{});
    Healthy(u, kT0, kT0 + kS);
    u.OnTvuCells({kT0 + kS, 20, 2, "special"});
    u.Evaluate(kT0 + kS);
    EXPECT_EQ(Find(u, "tvu_over_limit"), nullptr);
    u.OnTvuCells({kT0 + kS, 1, 1, "special"});
    u.Evaluate(kT0 + kS);
    ASSERT_NE(Find(u, "tvu_over_limit"), nullptr);  // 3 of 21 = 14 %
    EXPECT_NE(Find(u, "tvu_over_limit")->reason.find("order special"), std::string::npos);
}

TEST(StatusTracker, TvuAlarmConfigIsValidated) {
    StatusConfig c;
    EXPECT_TRUE(c.Validate().empty());
    c.tvu_alarm_percent = 101;
    c.tvu_window_s = 0;
    c.tvu_min_new_cells = 0;
    EXPECT_EQ(c.Validate().size(), 3u);
}

}  // namespace
}  // namespace pitmap::proc::live
