// SPDX-License-Identifier: MIT
// Scenario test of SLAM after a GNSS outage (issue 15): the gps-outage scenario (4 min without
// GNSS, the INS drifting metres) on seed 4, one of the draws where the rigid stage has to creep
// along the pit's eastern side (a straight corridor whose benches run with the track) before it
// settles. georef, calibrate and slam with the defaults, then the trajectory scored against the
// simulator's truth (figures: docs/decisions/005 and 002). The test fails when SLAM stops
// recovering the drift, or makes a GNSS-good stretch worse than the INS by more than the
// issue's 5 mm, or when the trajectory's stated 95 % horizontal radius after SLAM (the
// posterior with its perturbed-start spread, on by default) contains the true error in fewer
// than issue 36's 93 % of the pings, all and in the outage (docs/decisions/016 and 022).
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "tests/support/process.hpp"
#include "tests/support/scenario.hpp"

namespace {

namespace fs = std::filesystem;
using pitmap::test::kBin;
using pitmap::test::Quote;
using pitmap::test::ReadJson;
using pitmap::test::RunCommand;

TEST(GpsOutageScenario, SlamRecoversTheDriftAndKeepsTheGoodStretches) {
    const fs::path dir = pitmap::test::FreshDir("pitmap_gps_outage_scenario");
    std::string out;
    ASSERT_EQ(RunCommand(kBin + "/pitmap-sim synth --scenario gps-outage --seed 4 --out " +
                             Quote(dir / "sim"),
                         &out),
              0)
        << out;
    const fs::path p = dir / "products";
    ASSERT_EQ(
        RunCommand(kBin + "/pitmap georef " + Quote(dir / "sim/log") + " --out " + Quote(p), &out),
        0)
        << out;
    for (const char* stage : {"calibrate", "slam"}) {
        ASSERT_EQ(RunCommand(kBin + "/pitmap " + stage + " --out " + Quote(p), &out), 0)
            << stage << ": " << out;
    }
    const auto slam = ReadJson(p / "summary.json")["stages"]["slam"];
    EXPECT_GT(slam["sections_shifted"].get<int>(), 0) << "the coarse search moved no section";
    EXPECT_GT(slam["rigid_iterations"].get<int>(), 10) << "the rigid stage stopped early";

    const fs::path scores = dir / "scores.json";
    const auto s =
        pitmap::test::EvalScores(dir / "sim/truth", p, "--ate-window 30 --json " + Quote(scores));
    for (const char* k : {"trajectory_ate_rmse_before_m",
                          "trajectory_ate_rmse_m",
                          "trajectory_ate_worst_window_increase_m"}) {
        ASSERT_TRUE(s.count(k)) << k;
        RecordProperty(k, std::to_string(s.at(k)));
    }
    EXPECT_GT(s.at("trajectory_ate_rmse_before_m"), 1.0) << "the scenario no longer drifts";
    // Issue 36's 0.05 m (0.041 m measured with normals from 24 neighbours, decision 022).
    EXPECT_LT(s.at("trajectory_ate_rmse_m"), 0.05);
    EXPECT_LT(s.at("trajectory_ate_worst_window_increase_m"), 0.005);

    const auto u = ReadJson(scores)["trajectory_uncertainty"]["after"];
    ASSERT_TRUE(u.contains("all") && u.contains("outage")) << u.dump();
    const double within = u["all"]["share_within_h95"].get<double>();
    const double within_outage = u["outage"]["share_within_h95"].get<double>();
    RecordProperty("share_within_h95", std::to_string(within));
    RecordProperty("share_within_h95_outage", std::to_string(within_outage));
    EXPECT_GT(u["outage"]["poses"].get<int>(), 1000) << "the outage's pings were not scored";
    EXPECT_GE(within, 0.93) << "the stated 95 % radius misses the true error too often";
    // Issue 36's 93 % in the outage too: 95.9 % measured (docs/decisions/022; 83.6 % before,
    // when 10-neighbour normals pulled the optimum along a corridor's track).
    EXPECT_GE(within_outage, 0.93) << "in the outage";
    if (!HasFailure()) fs::remove_all(dir);  // 450 MB of simulation and products
}

}  // namespace
