// SPDX-License-Identifier: MIT
// Issue 35: `pitmap run` cleans the echoes of the simulator's artifact levels (light, typical,
// heavy) on the quarry's first 120 s (the high wall, the ramp, a shallow shelf; vendor files,
// the true boresight in the vehicle file), scored by pitmap-eval against the truth per beam.
// The bounds are what this cleaning reaches, with a margin (docs/cleaning.md has the figures
// and what is missing to the targets: >= 98 % of the artifact soundings rejected);
// the good soundings rejected stay under the 0.5 % in every slope class at every
// level. The run without artifacts is the reference for the products.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <map>
#include <string>

#include "tests/support/scenario.hpp"

namespace {

namespace fs = std::filesystem;
using pitmap::test::EvalScores;
using pitmap::test::FreshDir;
using pitmap::test::kBin;
using pitmap::test::Quote;
using pitmap::test::RunCommand;
using pitmap::test::SetTrueBoresight;

using Scores = std::map<std::string, double>;

Scores RunLevel(const fs::path& dir, const std::string& level) {
    const fs::path sim = dir / ("sim_" + level);
    const fs::path out = dir / ("P_" + level);
    std::string text;
    EXPECT_EQ(RunCommand(kBin +
                             "/pitmap-sim synth --scenario quarry --vendor-files --duration 120 "
                             "--echo-artifacts " +
                             level + " --out " + Quote(sim),
                         &text),
              0)
        << text;
    EXPECT_TRUE(SetTrueBoresight(sim));
    EXPECT_EQ(RunCommand(kBin + "/pitmap run " + Quote(sim / "log") + " --out " + Quote(out) +
                             " --no-report",
                         &text),
              0)
        << text;
    // Every ping georeferenced: the first one too (a latency correction of a few ms moves it
    // before the navigation's first sample; it was left out).
    const nlohmann::json pings = pitmap::test::ReadJson(out / "summary.json")["soundings"]["pings"];
    EXPECT_EQ(pings["georeferenced"], pings["in"]) << level << ": " << pings.dump();
    return EvalScores(sim / "truth", out);
}

double At(const Scores& s, const std::string& key) {
    const auto it = s.find(key);
    EXPECT_NE(it, s.end()) << "pitmap-eval printed no " << key;
    return it == s.end() ? 0.0 : it->second;
}

TEST(CleanScenario, EveryLevelCleanedAndTheProductsFollow) {
    const fs::path dir = FreshDir("pitmap_clean_levels");
    std::map<std::string, Scores> s;
    for (const std::string level : {"none", "light", "typical", "heavy"}) {
        s[level] = RunLevel(dir, level);
        ASSERT_FALSE(HasFailure()) << level;
        std::printf(
            "%-8s artifacts rejected %.4f, good rejected %.4f (slopes 0-20 %.4f, 20-45 "
            "%.4f, 45-91 %.4f), points RMS %.4f m, mesh mean abs %.4f m, beyond 1 m "
            "%.4f, completeness %.4f, DEM mean abs %.4f m\n",
            level.c_str(),
            level == "none" ? 0.0 : At(s[level], "artifact_rejected_share"),
            At(s[level], "good_rejected_share"),
            At(s[level], "good_rejected_share_slope_0_20"),
            At(s[level], "good_rejected_share_slope_20_45"),
            At(s[level], "good_rejected_share_slope_45_91"),
            At(s[level], "points_rms_m"),
            At(s[level], "mesh_mean_abs_m"),
            At(s[level], "mesh_share_beyond_1m"),
            At(s[level], "mesh_completeness"),
            At(s[level], "dem_mean_abs_m"));
    }
    const Scores& none = s["none"];
    // Measured (docs/cleaning.md): light 0.885, typical 0.981, heavy 0.975 of the artifact
    // soundings rejected (0.78, 0.937, 0.867 before the enclosed pieces grew along track over
    // steps short of a break and took breaks of 0.15 m; 0.76, 0.93, 0.80 before the one-sided
    // profile lines and the enclosed pieces); without the cleaning typical is 0.12 (the spike
    // filter's share).
    EXPECT_GE(At(s["light"], "artifact_rejected_share"), 0.86);
    EXPECT_GE(At(s["typical"], "artifact_rejected_share"), 0.975);
    EXPECT_GE(At(s["heavy"], "artifact_rejected_share"), 0.95);
    // Mid-water targets (fish) are the cleaning's best case.
    EXPECT_GE(At(s["typical"], "artifact_rejected_share_mid_water"), 0.97);
    // The bound (0.005) in every slope class, at every level. Measured 0.14-0.28 /
    // 0.24-0.26 / 0.18-0.29 % (0-20 / 20-45 / 45-91 deg) since a rejection continuous with the
    // terrain is terrain (0.40-0.71 / 0.50-0.65 / 0.37-0.56 % before: docs/decisions/014).
    for (const std::string level : {"none", "light", "typical", "heavy"}) {
        for (const char* slope : {"0_20", "20_45", "45_91"}) {
            EXPECT_LE(At(s[level], std::string("good_rejected_share_slope_") + slope), 0.005)
                << level << " slope " << slope;
        }
    }
    // The products: the mesh keeps (nearly) no false surface and its completeness, the DEM
    // stays near the clean run's.
    for (const std::string level : {"light", "typical", "heavy"}) {
        SCOPED_TRACE(level);
        EXPECT_LE(At(s[level], "mesh_share_beyond_1m"), 0.003);
        EXPECT_GE(At(s[level], "mesh_completeness"), At(none, "mesh_completeness") - 0.015);
        EXPECT_LE(At(s[level], "dem_mean_abs_m"), 1.8 * At(none, "dem_mean_abs_m"));
        EXPECT_LE(At(s[level], "points_rms_m"), 3.0 * At(none, "points_rms_m"));
    }
    EXPECT_LE(At(s["light"], "mesh_mean_abs_m"), 1.2 * At(none, "mesh_mean_abs_m"));
    if (!HasFailure()) fs::remove_all(dir);
}

}  // namespace
