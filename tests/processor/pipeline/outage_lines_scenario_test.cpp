// SPDX-License-Identifier: MIT
// Scenario test of SLAM after a 180 s GNSS outage on an independent-style quarry (issue 36
// item 4): the quarry scenario (benches, a 65 deg wall, a ramp, boulders) surveyed along star
// lines (`pitmap-sim synth --lines star`: six lines through the pit centre, so that the lines
// cross, unlike the corridor along a bench of gps-outage), without GNSS from 60 to 240 s and
// stopped 270 s after the start (the shortest survey that keeps the recovery; figures in
// docs/uncertainty.md). georef, calibrate and slam with the defaults, then the trajectory
// scored against the simulator's truth. Fails when the ATE after SLAM exceeds the issue's
// 0.08 m, or when the scenario no longer drifts.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "tests/support/process.hpp"
#include "tests/support/scenario.hpp"

namespace {

namespace fs = std::filesystem;
using pitmap::test::kBin;
using pitmap::test::Quote;
using pitmap::test::RunCommand;

TEST(OutageLinesScenario, SlamHoldsTheQuarryStarLinesThroughA180sOutage) {
    const fs::path dir = pitmap::test::FreshDir("pitmap_outage_lines_scenario");
    std::string out;
    ASSERT_EQ(RunCommand(kBin +
                             "/pitmap-sim synth --scenario quarry --lines star --duration "
                             "270 --gps-outage 60 240 --out " +
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
    const auto s = pitmap::test::EvalScores(dir / "sim/truth", p, "");
    for (const char* k : {"trajectory_ate_rmse_before_m", "trajectory_ate_rmse_m"}) {
        ASSERT_TRUE(s.count(k)) << k;
        RecordProperty(k, std::to_string(s.at(k)));
    }
    EXPECT_GT(s.at("trajectory_ate_rmse_before_m"), 1.0) << "the scenario no longer drifts";
    EXPECT_LT(s.at("trajectory_ate_rmse_m"), 0.08);
    if (!HasFailure()) fs::remove_all(dir);
}

}  // namespace
