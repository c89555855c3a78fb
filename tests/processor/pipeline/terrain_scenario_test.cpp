// SPDX-License-Identifier: MIT
// Scenario test of the mine-planning layers (issue 37 item 4; processor/hydro/terrain.hpp): on
// the quarry (benches, a 65 deg high wall, a ramp, boulders), the first 150 s georeferenced with
// the true boresight and gridded; pitmap-eval computes the same layers from the true heights at
// the DEM's nodes and compares. A crawler launched on the floor reaches ground there and not
// beyond the wall; a launch point away from any traversable ground, and a half-given one, say
// so.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "tests/support/process.hpp"
#include "tests/support/scenario.hpp"

namespace {

namespace fs = std::filesystem;
using pitmap::test::kBin;
using pitmap::test::Quote;
using pitmap::test::ReadJson;
using pitmap::test::RunCommand;
using pitmap::test::Scores;

TEST(TerrainScenario, SlopesStepsAndTheCrawlersReachMatchTheTrueTerrain) {
    const fs::path dir = pitmap::test::FreshDir("pitmap_terrain_scenario");
    std::string out;
    ASSERT_EQ(RunCommand(kBin + "/pitmap-sim synth --scenario quarry --duration 150 --out " +
                             Quote(dir / "sim"),
                         &out),
              0)
        << out;
    ASSERT_TRUE(pitmap::test::SetTrueBoresight(dir / "sim"));
    const fs::path P = dir / "P";
    ASSERT_EQ(
        RunCommand(kBin + "/pitmap georef " + Quote(dir / "sim/log") + " --out " + Quote(P), &out),
        0)
        << out;
    ASSERT_EQ(RunCommand(kBin + "/pitmap grid --out " + Quote(P), &out), 0) << out;
    ASSERT_TRUE(fs::exists(P / "terrain.tif") && fs::exists(P / "crawler.tif"));

    std::string text;
    ASSERT_EQ(RunCommand(kBin + "/pitmap-eval --truth " + Quote(dir / "sim/truth") +
                             " --products " + Quote(P),
                         &text),
              0)
        << text;
    const auto s = Scores(text);
    for (const char* k : {"terrain_nodes_scored",
                          "terrain_slope_mean_abs_deg",
                          "terrain_step_mean_abs_m",
                          "terrain_class_agreement",
                          "terrain_blocked_recall",
                          "terrain_blocked_false_share"}) {
        ASSERT_TRUE(s.count(k)) << k;
        RecordProperty(k, std::to_string(s.at(k)));
    }
    EXPECT_GT(s.at("terrain_nodes_scored"), 100000);
    EXPECT_LT(s.at("terrain_slope_mean_abs_deg"), 1.5);
    EXPECT_LT(s.at("terrain_step_mean_abs_m"), 0.06);
    EXPECT_GT(s.at("terrain_class_agreement"), 0.95);
    EXPECT_GT(s.at("terrain_blocked_recall"), 0.95);
    EXPECT_LT(s.at("terrain_blocked_false_share"), 0.03);

    // A launch point at the grid's middle (the pit's floor in this part of the survey).
    const auto grid = ReadJson(P / "summary.json")["stages"]["grid"];
    const double e = grid["x0_m"].get<double>() + 0.5 * grid["nx"].get<int>() * 0.1;
    const double n = grid["y0_m"].get<double>() + 0.5 * grid["ny"].get<int>() * 0.1;
    std::ofstream(dir / "launch.yaml") << "terrain:\n  launch_easting: " << std::to_string(e)
                                       << "\n  launch_northing: " << std::to_string(n) << "\n";
    ASSERT_EQ(RunCommand(kBin + "/pitmap grid --out " + Quote(P) + " --config " +
                             Quote(dir / "launch.yaml"),
                         &out),
              0)
        << out;
    const auto t = ReadJson(P / "summary.json")["stages"]["grid"]["terrain"];
    ASSERT_TRUE(t["launch_found"].get<bool>()) << t.dump();
    const auto& area = t["area_by_class_m2"];
    EXPECT_GT(area["reachable"].get<double>(), 100.0) << t.dump();
    // Not everything traversable is reachable: the wall and the benches' edges cut some off.
    EXPECT_GT(area["traversable, not reachable"].get<double>(), 10.0) << t.dump();
    EXPECT_GT(area["too steep"].get<double>() + area["step obstacle"].get<double>(), 100.0);

    // Far outside the survey: nothing to snap to, said, and still a product.
    out.clear();
    std::ofstream(dir / "far.yaml") << "terrain:\n  launch_easting: " << std::to_string(e + 5000)
                                    << "\n  launch_northing: " << std::to_string(n) << "\n";
    ASSERT_EQ(
        RunCommand(kBin + "/pitmap grid --out " + Quote(P) + " --config " + Quote(dir / "far.yaml"),
                   &out),
        0)
        << out;
    EXPECT_NE(out.find("no traversable node within"), std::string::npos) << out;
    EXPECT_FALSE(ReadJson(P / "summary.json")["stages"]["grid"]["terrain"]["launch_found"]);

    // Half a launch point is a configuration problem, listed at start-up (exit 2).
    out.clear();
    std::ofstream(dir / "half.yaml") << "terrain:\n  launch_easting: 1.0\n  window_m: -1\n";
    const int status = RunCommand(
        kBin + "/pitmap grid --out " + Quote(P) + " --config " + Quote(dir / "half.yaml"), &out);
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 2) << status << "\n" << out;
    EXPECT_NE(out.find("terrain.launch_easting and terrain.launch_northing"), std::string::npos)
        << out;
    EXPECT_NE(out.find("terrain.window_m"), std::string::npos) << out;
    if (!HasFailure()) fs::remove_all(dir);
}

}  // namespace
