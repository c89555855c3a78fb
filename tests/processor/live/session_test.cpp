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
#include "tests/processor/live/live_feeder.hpp"

namespace pitmap::proc::live {
namespace {

using namespace test;  // NOLINT: the feeder and its constants

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

// The status says where the events come from; a replay that ended is "finished" and its
// silence raises no no_messages alarm (a live feed's does).
TEST(LiveSession, AnEndedReplayIsFinishedNotSilent) {
    for (const bool replay : {false, true}) {
        LiveSession s(Config(), {}, true);
        if (replay) s.MarkReplay();
        Feeder f(s);
        for (std::int64_t t = 0; t <= kS; t += 50'000) f.Nav(t);
        s.Tick(kHost0 + kS, true);
        nlohmann::json st = s.StatusJson(kHost0 + kS);
        EXPECT_EQ(st["source"]["kind"], replay ? "replay" : "lcm");
        EXPECT_FALSE(st["source"]["finished"].get<bool>());
        if (replay) s.MarkReplayFinished();
        s.Tick(kHost0 + 20 * kS, true);
        st = s.StatusJson(kHost0 + 20 * kS);
        EXPECT_EQ(st["source"]["finished"].get<bool>(), replay);
        bool silent = false;
        for (const auto& a : st["alarms"]) silent = silent || a["id"] == "no_messages";
        EXPECT_EQ(silent, !replay) << st["alarms"].dump();
    }
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
    ASSERT_EQ(back->grid.layers.size(), 7u);
    EXPECT_EQ(back->grid.layers[0].name, "depth");
    EXPECT_EQ(back->grid.layers[5].name, "tvu_95");
    EXPECT_EQ(back->grid.layers[6].name, "tvu_meets_order");
    EXPECT_NE(back->horizontal_name.find("UTM zone 29N"), std::string::npos)
        << back->horizontal_name;
    const CoverageStats g = s.GridStats();
    EXPECT_EQ(back->grid.nx, g.max_ix - g.min_ix + 1);
    int filled = 0;
    for (float v : back->grid.layers[3].values) filled += std::isfinite(v) ? 1 : 0;
    EXPECT_EQ(filled, g.filled_cells);
    int meets = 0, tvu = 0;
    for (std::size_t k = 0; k < back->grid.layers[5].values.size(); ++k) {
        const float t = back->grid.layers[5].values[k];
        if (!std::isfinite(t)) continue;
        ++tvu;
        EXPECT_GT(t, 0.05f);
        EXPECT_LT(t, 0.2f);
        meets += back->grid.layers[6].values[k] == 1.0f ? 1 : 0;
    }
    EXPECT_EQ(tvu, g.filled_cells);
    EXPECT_EQ(meets, g.filled_cells);
    std::filesystem::remove_all(dir);
}

std::vector<std::uint8_t> FromBase64(const std::string& in) {
    std::vector<std::uint8_t> out;
    std::uint32_t acc = 0;
    int bits = 0;
    for (char c : in) {
        int v = -1;
        if (c >= 'A' && c <= 'Z') v = c - 'A';
        if (c >= 'a' && c <= 'z') v = c - 'a' + 26;
        if (c >= '0' && c <= '9') v = c - '0' + 52;
        if (c == '+') v = 62;
        if (c == '/') v = 63;
        if (v < 0) continue;  // '=' padding
        acc = (acc << 6) | static_cast<std::uint32_t>(v);
        bits += 6;
        if (bits >= 8) {
            bits -= 8;
            out.push_back(static_cast<std::uint8_t>((acc >> bits) & 0xFF));
        }
    }
    return out;
}

// Every tile's TVU bytes, with its count bytes: (count, tvu) for every filled cell.
std::vector<std::pair<int, int>> FilledTvuBytes(const nlohmann::json& tiles) {
    std::vector<std::pair<int, int>> out;
    for (const auto& tile : tiles["tiles"]) {
        const auto tvu = FromBase64(tile["tvu"]);
        const auto count = FromBase64(tile["count"]);
        EXPECT_EQ(tvu.size(), static_cast<std::size_t>(kTileCells * kTileCells));
        EXPECT_EQ(count.size(), tvu.size());
        for (std::size_t k = 0; k < std::min(tvu.size(), count.size()); ++k) {
            EXPECT_EQ(count[k] == 0, tvu[k] == 0) << k;  // 0 = empty, and only then
            if (count[k] > 0) out.emplace_back(count[k], tvu[k]);
        }
    }
    return out;
}

// 20 s of the flat 10 m survey with a given sensor error model (and reported INS height sigma);
// the session afterwards.
void Survey(LiveSession& s, double height_sigma_m = 0) {
    Feeder f(s);
    f.height_sigma_m = height_sigma_m;
    for (std::int64_t t = 0; t <= 20 * kS; t += 50'000) {
        f.Nav(t);
        if (t % 100'000 == 0) f.Ping(t);
        s.Tick(kHost0 + t);
    }
    s.Tick(kHost0 + 20 * kS, true);
}

std::set<std::string> AlarmIds(LiveSession& s) {
    std::set<std::string> ids;
    const nlohmann::json alarms = s.AlarmsJson();
    for (const auto& a : alarms["active"]) ids.insert(a["id"].get<std::string>());
    return ids;
}

TEST(LiveSession, TvuOfTheDefaultModelMeetsOrder1a) {
    LiveSession s(Config(), {}, true);
    Survey(s);
    const nlohmann::json st = s.StatusJson(kHost0 + 20 * kS);
    const nlohmann::json& t = st["grid"]["tvu"];
    EXPECT_EQ(t["order"], "1a");
    EXPECT_EQ(t["cells_failing"], 0);
    EXPECT_EQ(t["cells_meeting"], st["grid"]["filled_cells"]);
    EXPECT_DOUBLE_EQ(t["share_meeting"].get<double>(), 1.0);
    // By hand at nadir (level vehicle, 10 m, default SensorErrorModel, no INS sigma reported:
    // the model's): range (0.02 + 0.002 * 10)^2 + mean sound speed (10 * 1 / 1500)^2 + INS height
    // 0.015^2 + noise 0.005^2 + lever arm 0.01^2 = 0.0019944 m^2 -> 1.96 * 0.04466 = 0.0875 m;
    // the outer beams (60 deg, 20 m range) come to about 0.08 m.
    EXPECT_NEAR(t["last_batch_median_tvu_m"].get<double>(), 0.0875, 0.01);
    EXPECT_EQ(t["pings_with_ins_sigma"], 0);
    EXPECT_EQ(t["pings_with_model_sigma"], 201);
    EXPECT_FALSE(AlarmIds(s).count("tvu_over_limit"));

    // The tiles carry one TVU byte per cell: 0 empty, else mean TVU in 2 cm steps, bit 7 = fails.
    const nlohmann::json tiles = s.TilesJson(0, -1);
    EXPECT_EQ(tiles["tvu"]["order"], "1a");
    EXPECT_DOUBLE_EQ(tiles["tvu"]["limit_a_m"].get<double>(), 0.5);
    EXPECT_DOUBLE_EQ(tiles["tvu"]["limit_b"].get<double>(), 0.013);
    EXPECT_DOUBLE_EQ(tiles["tvu"]["step_m"].get<double>(), 0.02);
    EXPECT_EQ(tiles["stats"]["cells_tvu_failing"], 0);
    // Every filled cell: mean TVU 0.08..0.10 m -> 4 or 5 steps of 2 cm, bit 7 clear (meets).
    const auto cells = FilledTvuBytes(tiles);
    EXPECT_EQ(static_cast<std::int64_t>(cells.size()),
              st["grid"]["filled_cells"].get<std::int64_t>());
    for (const auto& [count, tvu] : cells) {
        EXPECT_TRUE(tvu == 4 || tvu == 5) << tvu;
    }
}

TEST(LiveSession, ABadErrorModelFailsTheOrderAndRaisesTheAlarm) {
    LiveConfig c = Config();
    c.tpu.model.position_noise_m = 0.3;  // 1.96 * 0.3 = 0.59 m > 0.517 m (1a at 10 m)
    LiveSession s(c, {}, true);
    Survey(s);
    const nlohmann::json st = s.StatusJson(kHost0 + 20 * kS);
    const nlohmann::json& t = st["grid"]["tvu"];
    EXPECT_EQ(t["cells_meeting"], 0);
    EXPECT_EQ(t["cells_failing"], st["grid"]["filled_cells"]);
    EXPECT_EQ(t["soundings_over"], 201 * 121);
    EXPECT_GT(t["last_batch_median_tvu_m"].get<double>(), 0.59);
    bool found = false;
    for (const auto& a : st["alarms"]) {
        if (a["id"] != "tvu_over_limit") continue;
        found = true;
        const std::string reason = a["reason"];
        EXPECT_NE(reason.find("order 1a"), std::string::npos) << reason;
        EXPECT_NE(reason.find("100 % of new cells"), std::string::npos) << reason;
    }
    EXPECT_TRUE(found) << st["alarms"].dump();
    // The tiles say every cell fails: bit 7 set, mean TVU >= 0.59 m (30 steps).
    const nlohmann::json tiles = s.TilesJson(0, -1);
    EXPECT_EQ(tiles["stats"]["cells_tvu_failing"], st["grid"]["filled_cells"]);
    for (const auto& [count, tvu] : FilledTvuBytes(tiles)) {
        EXPECT_GE(tvu, 0x80 + 29) << tvu;
    }
    // Held to order 2 (1.026 m at 10 m) the same survey passes.
    c.grid.s44_order = "2";
    LiveSession lax(c, {}, true);
    Survey(lax);
    EXPECT_EQ(lax.StatusJson(kHost0)["grid"]["tvu"]["cells_failing"], 0);
    EXPECT_FALSE(AlarmIds(lax).count("tvu_over_limit"));
}

TEST(LiveSession, TheInsSigmaComesFromTheLiveNavigation) {
    // INSPVAX reports a height sigma of 0.3 m: 1.96 * 0.3 = 0.59 m > the 1a limit, although the
    // error model is the default one.
    LiveSession s(Config(), {}, true);
    Survey(s, 0.3);
    const nlohmann::json t = s.StatusJson(kHost0)["grid"]["tvu"];
    EXPECT_EQ(t["pings_with_ins_sigma"], 201);
    EXPECT_EQ(t["pings_with_model_sigma"], 0);
    EXPECT_EQ(t["cells_meeting"], 0);
    EXPECT_TRUE(AlarmIds(s).count("tvu_over_limit")) << s.AlarmsJson().dump();
}

}  // namespace
}  // namespace pitmap::proc::live
