// SPDX-License-Identifier: MIT
// Scenario test of the SLAM stage reading the georeferenced view a block at a time from its
// scratch file (issue 38, docs/decisions/043-slam-stage-by-view-blocks.md): the demo survey
// (overlapping passes, a drifting INS), georeferenced once, SLAM run twice from copies of one
// products folder, with blocks of 1 024 soundings (the smallest: a ping's soundings straddle
// blocks) and with one block holding the whole view. SLAM's input (its slices' figures, the
// range noise of its gate, points_initial.ply), the trajectory it leaves and its sigmas
// (trajectory.csv, trajectory_sigma.csv) and the soundings moved onto it (points.ply) are the
// same, byte for byte. The pings' per-beam arrays wait on disk through the stage and come back
// bit for bit (decision 044).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "tests/support/process.hpp"
#include "tests/support/scenario.hpp"

namespace {

namespace fs = std::filesystem;
using pitmap::test::BytesWithoutUtcTimes;
using pitmap::test::kBin;
using pitmap::test::Quote;
using pitmap::test::ReadJson;
using pitmap::test::RunCommand;

// summary.json's SLAM record: what the view gives SLAM (its input, bit for bit) and what SLAM
// made of it, but the figures its parallel sums leave to the last bits (the costs and
// consistencies, the arrays' capacities: they differ between two runs of one folder and one
// config, by 1e-15 relative) and the times, memory and blocks.
nlohmann::json SlamFigures(const fs::path& summary) {
    const nlohmann::json c = ReadJson(summary)["stages"]["slam"];
    nlohmann::json out;
    for (const char* k : {"slices",
                          "points",
                          "points_used",
                          "expected_consistency_m",
                          "sections",
                          "section_links",
                          "poses",
                          "termination",
                          "rigid_iterations",
                          "semi_rigid_iterations"}) {
        out[k] = c.value(k, nlohmann::json());
    }
    return out;
}

TEST(SlamBlocksScenario, BlocksOfTheSpilledViewGiveTheWholeViewsTrajectory) {
    const fs::path dir = pitmap::test::FreshDir("pitmap_slam_blocks_scenario");
    std::string out;
    ASSERT_EQ(
        RunCommand(kBin + "/pitmap-sim synth --scenario demo --out " + Quote(dir / "sim"), &out), 0)
        << out;
    const fs::path small = dir / "small", whole = dir / "whole";
    ASSERT_EQ(
        RunCommand(kBin + "/pitmap georef " + Quote(dir / "sim/log") + " --out " + Quote(small),
                   &out),
        0)
        << out;
    fs::copy(small, whole, fs::copy_options::recursive);
    // The posterior's perturbed-start runs are left out: they test nothing of the view's blocks.
    std::ofstream(dir / "small.yaml") << "run:\n  block_soundings: 1024\n"
                                      << "slam:\n  posterior_start_runs: 0\n";
    std::ofstream(dir / "whole.yaml") << "run:\n  block_soundings: 100000000\n"
                                      << "  memory_budget_mb: 100000\n"
                                      << "slam:\n  posterior_start_runs: 0\n";
    for (const fs::path& p : {small, whole}) {
        const fs::path config = dir / (p.filename().string() + ".yaml");
        ASSERT_EQ(RunCommand(kBin + "/pitmap slam --out " + Quote(p) + " --config " + Quote(config),
                             &out),
                  0)
            << out;
        EXPECT_FALSE(fs::exists(p / ".partial-view_points")) << p;
        for (const auto& e : fs::directory_iterator(p)) {
            EXPECT_EQ(e.path().filename().string().rfind(".partial-slam_beam_", 0),
                      std::string::npos)
                << e.path();
        }
        // The pings' per-beam arrays waited on disk through SLAM (decision 044).
        EXPECT_GT(ReadJson(p / "summary.json")["stages"]["slam"].value("beam_arrays_aside_mb", 0.0),
                  0.0)
            << p;
    }
    const nlohmann::json a = SlamFigures(small / "summary.json");
    const nlohmann::json b = SlamFigures(whole / "summary.json");
    ASSERT_GT(a.value("points", 0), 100 * 1024) << "too few soundings for many blocks";
    EXPECT_EQ(ReadJson(small / "summary.json")["stages"]["slam"].value("block_soundings", 0), 1024);
    // SLAM moved the survey: the blocks' move of the soundings is exercised.
    EXPECT_GT(
        ReadJson(small / "summary.json")["stages"]["slam"].value("position_change_rms_m", 0.0),
        0.0);
    EXPECT_EQ(a, b) << a.dump(1) << "\n" << b.dump(1);
    for (const char* f : {"trajectory.csv",
                          "trajectory_initial.csv",
                          "trajectory_sigma.csv",
                          "points_initial.ply",
                          "points.ply"}) {
        ASSERT_TRUE(fs::exists(whole / f)) << f;
        EXPECT_TRUE(BytesWithoutUtcTimes(small / f) == BytesWithoutUtcTimes(whole / f)) << f;
    }
    // The beams came back bit for bit (survey.pitmap was saved with them): SLAM again on the
    // folder georeferences the same view from them.
    const std::string first = BytesWithoutUtcTimes(whole / "points_initial.ply");
    ASSERT_EQ(RunCommand(kBin + "/pitmap slam --out " + Quote(whole) + " --config " +
                             Quote(dir / "whole.yaml"),
                         &out),
              0)
        << out;
    EXPECT_TRUE(BytesWithoutUtcTimes(whole / "points_initial.ply") == first);
}

}  // namespace
