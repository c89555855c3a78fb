// SPDX-License-Identifier: MIT
// LiveSession end to end on encoded LCM messages: a level vehicle heading north at 1 m/s over a
// flat bottom 10 m down. Pings are georeferenced only once navigation brackets them, the grid
// shows the swath at the right depth, the JSON documents fit their byte budget (and say they
// were thinned), garbage is counted, and a snapshot reads back as a GeoTIFF.
#include "processor/live/session.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <pitmap/daemon_status_t.hpp>
#include <pitmap/ins_pva_t.hpp>
#include <pitmap/multibeam_ping_t.hpp>
#include <set>

#include "common/geodesy.hpp"
#include "lcmtypes/log/channels.hpp"
#include "processor/io/grid_io.hpp"

namespace pitmap::proc::live {
namespace {

constexpr double kDepthM = 10.0;
constexpr std::int64_t kHost0 = 1'781'500'000'000'000;
constexpr std::int64_t kGps0 = 1'465'000'000'000'000;
constexpr std::int64_t kS = 1'000'000;
const Geodetic kStart{40.0, -7.0, 100.0};

template <class M>
std::vector<std::uint8_t> Encode(const M& m) {
    std::vector<std::uint8_t> b(static_cast<std::size_t>(m.getEncodedSize()));
    m.encode(b.data(), 0, static_cast<int>(b.size()));
    return b;
}

class Feeder {
public:
    explicit Feeder(LiveSession& s) : s_(s), world_(kStart) {}
    void Nav(std::int64_t dt_us) {
        pitmap::ins_pva_t m{};
        m.utime = kHost0 + dt_us;
        m.utime_gps = kGps0 + dt_us;
        const Geodetic p = world_.FromEnu(Eigen::Vector3d(0, 1.0 * dt_us * 1e-6, 0));
        m.latitude_deg = p.latitude_deg;
        m.longitude_deg = p.longitude_deg;
        m.height_ellipsoid_m = p.height_m;
        m.velocity_north_mps = 1.0;
        m.ins_status = 3;
        m.position_type = -1;
        m.has_stddev = 0;
        Send(std::string(lcmlog::kChannelInsPva) + "NOVATEL_COM1", Encode(m), m.utime);
    }
    void Ping(std::int64_t dt_us) {
        pitmap::multibeam_ping_t m{};
        m.utime = kHost0 + dt_us + 2000;
        m.utime_gps = kGps0 + dt_us;
        m.range_resolution_m = 0.002f;
        m.start_angle_deg = -60;
        m.angle_increment_deg = 1.0f;
        m.sound_speed_mps = 1500;
        m.num_beams = 121;
        for (int i = 0; i < m.num_beams; ++i) {
            const double th = (m.start_angle_deg + i * m.angle_increment_deg) * M_PI / 180.0;
            m.range_counts.push_back(
                static_cast<std::int32_t>(std::lround(kDepthM / std::cos(th) / 0.002)));
        }
        m.num_intensities = 0;
        Send(std::string(lcmlog::kChannelMultibeamPing) + "DELTAT_UDP", Encode(m), m.utime);
    }
    void Send(const std::string& ch, const std::vector<std::uint8_t>& b, std::int64_t utime) {
        s_.OnEvent(ch, b.data(), b.size(), utime);
    }

private:
    LiveSession& s_;
    LocalTangentFrame world_;
};

LiveConfig Config() {
    LiveConfig c;
    c.grid.cell_size_m = 1.0;
    c.process_interval_s = 0;
    c.holiday_refresh_s = 0;
    return c;
}

TEST(LiveSession, PingsWaitForNavigationThenFillTheGridAtTheTrueDepth) {
    LiveSession s(Config(), {}, true);
    Feeder f(s);
    f.Nav(0);
    f.Ping(50'000);  // after the newest INS sample: waits
    s.Tick(kHost0 + 60'000);
    EXPECT_EQ(s.StatusJson(kHost0)["georef"]["pings_waiting"], 1);
    EXPECT_EQ(s.grid_version(), 0u);
    f.Nav(100'000);  // now bracketed
    s.Tick(kHost0 + 110'000);
    EXPECT_EQ(s.StatusJson(kHost0)["georef"]["pings_waiting"], 0);
    EXPECT_EQ(s.StatusJson(kHost0)["georef"]["pings_georeferenced"], 1);
    EXPECT_GT(s.grid_version(), 0u);

    // 20 s of survey: INS at 20 Hz, pings at 10 Hz.
    for (std::int64_t t = 150'000; t <= 20 * kS; t += 50'000) {
        f.Nav(t);
        if (t % 100'000 == 0) f.Ping(t);
        s.Tick(kHost0 + t);
    }
    s.Tick(kHost0 + 20 * kS, true);
    const CoverageStats g = s.GridStats();
    // 121 beams hit a 10 m plane from -60 to +60 deg: a swath 2 * 10 * tan(60 deg) = 34.6 m wide
    // and 20 m long.
    EXPECT_NEAR(g.min_depth_m, kDepthM, 0.05);
    EXPECT_NEAR(g.max_depth_m, kDepthM, 0.05);
    EXPECT_NEAR(static_cast<double>(g.max_ix - g.min_ix + 1), 35.0, 2.0);
    EXPECT_NEAR(static_cast<double>(g.max_iy - g.min_iy + 1), 20.0, 2.0);
    const nlohmann::json st = s.StatusJson(kHost0 + 20 * kS);
    EXPECT_EQ(st["georef"]["pings_georeferenced"], 200);
    EXPECT_EQ(st["georef"]["soundings"], 200 * 121);
    EXPECT_EQ(st["grid"]["soundings"], 200 * 121);
    EXPECT_EQ(st["lcm_channels"]["MULTIBEAM_PING_DELTAT_UDP"]["messages"], 200);
    EXPECT_NEAR(st["ping_rate_hz"].get<double>(), 10.0, 0.1);
    EXPECT_TRUE(st["alarms"].empty()) << st["alarms"].dump();
}

TEST(LiveSession, TilesAndSoundingsFitTheirBudgetAndSayWhenThinned) {
    LiveSession s(Config(), {}, true);
    Feeder f(s);
    for (std::int64_t t = 0; t <= 40 * kS; t += 50'000) {
        f.Nav(t);
        if (t % 100'000 == 0) f.Ping(t);
        s.Tick(kHost0 + t);
    }
    s.Tick(kHost0 + 40 * kS, true);
    const nlohmann::json all = s.TilesJson(0, -1);
    const std::size_t n_tiles = all["tiles"].size();
    ASSERT_GE(n_tiles, 3u);
    EXPECT_FALSE(all["thinned"].get<bool>());
    EXPECT_EQ(all["pending_tiles"], 0);
    EXPECT_EQ(all["next_since"], s.grid_version());
    // Nothing new since the last version.
    EXPECT_TRUE(s.TilesJson(all["next_since"], -1)["tiles"].empty());
    // A budget for about one tile: fewer tiles, thinned, and the rest follows on the next ask.
    const std::int64_t budget = static_cast<std::int64_t>(all["tiles"][0].dump().size()) + 1000;
    const nlohmann::json part = s.TilesJson(0, budget);
    EXPECT_LE(part.dump().size(), static_cast<std::size_t>(budget));
    EXPECT_TRUE(part["thinned"].get<bool>());
    EXPECT_LT(part["tiles"].size(), n_tiles);
    EXPECT_GT(part["pending_tiles"].get<int>(), 0);
    std::uint64_t since = part["next_since"];
    std::size_t got = part["tiles"].size();
    for (int k = 0; k < 20 && since < s.grid_version(); ++k) {
        const nlohmann::json more = s.TilesJson(since, budget);
        got += more["tiles"].size();
        since = more["next_since"];
    }
    EXPECT_EQ(since, s.grid_version());
    EXPECT_GE(got, n_tiles);

    const nlohmann::json pts = s.SoundingsJson(0, -1);
    EXPECT_EQ(pts["new"], 400 * 121 + 121);
    EXPECT_EQ(pts["stride"], 1);
    EXPECT_FALSE(pts["thinned"].get<bool>());
    const nlohmann::json thin = s.SoundingsJson(0, 50'000);
    EXPECT_TRUE(thin["thinned"].get<bool>());
    EXPECT_GT(thin["stride"].get<int>(), 1);
    EXPECT_LE(thin.dump().size(), 50'000u);
    EXPECT_EQ(s.SoundingsJson(pts["seq"], -1)["new"], 0);
}

TEST(LiveSession, GarbageIsCountedPerChannelNeverFatal) {
    LiveSession s(Config(), {}, true);
    const std::vector<std::uint8_t> junk = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12};
    for (const std::string& ch : {std::string(lcmlog::kChannelInsPva) + "X",
                                  std::string(lcmlog::kChannelMultibeamPing) + "Y",
                                  std::string(lcmlog::kChannelDaemonStatus),
                                  std::string(lcmlog::kChannelClockSync)}) {
        s.OnEvent(ch, junk.data(), junk.size(), kHost0);
        s.OnEvent(ch, junk.data(), 0, kHost0);
    }
    s.OnEvent("SOMETHING_ELSE", junk.data(), junk.size(), kHost0);  // not ours: counted only
    s.Tick(kHost0, true);
    EXPECT_EQ(s.counts().decode_failures, 8);
    EXPECT_EQ(s.counts().events, 9);
    const nlohmann::json st = s.StatusJson(kHost0);
    EXPECT_EQ(st["lcm_channels"]["DAEMON_STATUS"]["decode_failures"], 2);
    EXPECT_EQ(st["lcm_channels"]["SOMETHING_ELSE"]["messages"], 1);
}

TEST(LiveSession, DaemonStatusDrivesDiskAndClockAlarms) {
    LiveSession s(Config(), {}, true);
    pitmap::daemon_status_t d{};
    d.utime = kHost0;
    d.hostname = "asv";
    d.logging = pitmap::daemon_status_t::LOGGING_DISK_GUARD;
    d.disk_free_bytes = 100'000'000;
    d.host_clock.utime = kHost0;
    d.host_clock.source = 1;
    d.host_clock.state = 1;
    d.host_clock.leap_seconds = 18;
    // 2.5 ms behind UTC: GPS us since 1980 = Unix us - 315964800 s + 18 s (+ 2500 us).
    d.host_clock.offset_us = -315'964'800'000'000LL + 18'000'000LL + 2'500;
    d.sonar_clock.source = 3;
    d.num_channels = 0;
    const auto b = Encode(d);
    s.OnEvent(std::string(lcmlog::kChannelDaemonStatus), b.data(), b.size(), kHost0);
    s.Tick(kHost0, true);
    EXPECT_EQ(s.counts().decode_failures, 0);
    std::set<std::string> ids;
    const nlohmann::json alarms = s.AlarmsJson();
    for (const auto& a : alarms["active"]) ids.insert(a["id"].get<std::string>());
    EXPECT_TRUE(ids.count("disk_low"));
    EXPECT_TRUE(ids.count("clock_not_locked"));
    const nlohmann::json st = s.StatusJson(kHost0);
    EXPECT_EQ(st["daemon"]["logging"], "disk_guard");
    ASSERT_EQ(st["clocks"].size(), 1u);
    EXPECT_NEAR(st["clocks"][0]["utc_minus_clock_us"].get<double>(), 2500.0, 1e-3);
}

TEST(LiveSession, SnapshotReadsBackAsAGeoTiff) {
    LiveSession s(Config(), {}, true);
    EXPECT_FALSE(s.WriteSnapshot(testing::TempDir() + "/live_snapshot_empty"));
    Feeder f(s);
    for (std::int64_t t = 0; t <= 5 * kS; t += 50'000) {
        f.Nav(t);
        if (t % 100'000 == 0) f.Ping(t);
    }
    s.Tick(kHost0 + 5 * kS, true);
    const std::string dir = testing::TempDir() + "/live_snapshot";
    auto path = s.WriteSnapshot(dir);
    ASSERT_TRUE(path) << path.error().message;
    auto back = io::ReadGrid(*path);
    ASSERT_TRUE(back) << back.error().message;
    EXPECT_EQ(back->grid.layers.size(), 5u);
    EXPECT_EQ(back->grid.layers[0].name, "depth");
    EXPECT_NE(back->horizontal_name.find("UTM zone 29N"), std::string::npos)
        << back->horizontal_name;
    const CoverageStats g = s.GridStats();
    EXPECT_EQ(back->grid.nx, g.max_ix - g.min_ix + 1);
    int filled = 0;
    for (float v : back->grid.layers[3].values) filled += std::isfinite(v) ? 1 : 0;
    EXPECT_EQ(filled, g.filled_cells);
    std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace pitmap::proc::live
