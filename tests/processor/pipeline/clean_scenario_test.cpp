// SPDX-License-Identifier: MIT
// Issue 35: `pitmap run` cleans the echoes of the simulator's artifact levels (light, typical,
// heavy) on the quarry's first 120 s (the high wall, the ramp, a shallow shelf; vendor files,
// the true boresight in the vehicle file), scored by pitmap-eval against the truth per beam.
// The bounds are the at typical (docs/cleaning.md has the figures; the points RMS at
// typical was held below the target until the near-field test, docs/decisions/
// 014-bounds-held-below-target.md and 024-near-field-echoes.md), and what this cleaning reaches,
// with a margin, at light and heavy; the good soundings rejected stay under the 0.5 % in
// every slope class at every level. The run without
// artifacts, the same survey (seed, track, navigation errors: only the artifacts differ), is
// the reference for the products.
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

// seed: pitmap-sim's --seed (empty: the scenario's own).
Scores RunLevel(const fs::path& dir, const std::string& level, const std::string& seed = "") {
    const fs::path sim = dir / ("sim_" + level);
    const fs::path out = dir / ("P_" + level);
    std::string text;
    EXPECT_EQ(
        RunCommand(kBin +
                       "/pitmap-sim synth --scenario quarry --vendor-files --duration 120 "
                       "--echo-artifacts " +
                       level + (seed.empty() ? "" : " --seed " + seed) + " --out " + Quote(sim),
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
    // Measured (docs/cleaning.md): light 0.965, typical 0.998, heavy 0.980 of the artifact
    // soundings rejected (0.885, 0.987, 0.976 before the near-field test; typical 0.981 before a
    // cluster sounding whose ray went through the terrain was multipath; 0.78, 0.937, 0.867
    // before the enclosed pieces grew along track over steps short of a break and took breaks
    // of 0.15 m); without the cleaning typical is 0.12 (the spike filter's share). Typical
    // holds the 0.98.
    EXPECT_GE(At(s["light"], "artifact_rejected_share"), 0.95);
    EXPECT_GE(At(s["typical"], "artifact_rejected_share"), 0.98);
    EXPECT_GE(At(s["heavy"], "artifact_rejected_share"), 0.97);
    // Bubble sweep-down at typical: 0.999 (0.966 before the near-field test: 52 soundings of
    // clouds 1-3 m above the shelf, all of the points RMS's excess over the clean run).
    EXPECT_GE(At(s["typical"], "artifact_rejected_share_bubble"), 0.99);
    // Mid-water targets (fish) are the cleaning's best case; the long ghost behind the high
    // wall (19 pings x 11 beams at 18-22 m) is rejected whole (1.000; 0.976 before).
    EXPECT_GE(At(s["typical"], "artifact_rejected_share_mid_water"), 0.97);
    EXPECT_GE(At(s["typical"], "artifact_rejected_share_multipath"), 0.99);
    // The bound (0.005) in every slope class, at every level. Measured 0.08-0.32 /
    // 0.09-0.13 / 0.16-0.28 % (0-20 / 20-45 / 45-91 deg).
    for (const std::string level : {"none", "light", "typical", "heavy"}) {
        for (const char* slope : {"0_20", "20_45", "45_91"}) {
            EXPECT_LE(At(s[level], std::string("good_rejected_share_slope_") + slope), 0.005)
                << level << " slope " << slope;
        }
    }
    // The products against the run without artifacts. The bounds at typical: the mesh
    // beyond 1 m <= 0.05 % (measured 0.00 %), its mean abs error within 10 % (+2 %), its
    // completeness within 0.5 point (-0.36; -0.43 before decision 026), and light and heavy held
    // to the same mesh bounds
    // (0.00 / 0.01 %, +2 / +7 %); heavy's completeness is 1.2 points below (the 1.5 held).
    for (const std::string level : {"light", "typical", "heavy"}) {
        SCOPED_TRACE(level);
        EXPECT_LE(At(s[level], "mesh_share_beyond_1m"), 0.0005);
        EXPECT_LE(At(s[level], "mesh_mean_abs_m"), 1.10 * At(none, "mesh_mean_abs_m"));
        EXPECT_GE(At(s[level], "mesh_completeness"), At(none, "mesh_completeness") - 0.015);
        // DEM mean abs: +2 / +5 / +11 % (light, typical, heavy).
        EXPECT_LE(At(s[level], "dem_mean_abs_m"), 1.15 * At(none, "dem_mean_abs_m"));
    }
    EXPECT_GE(At(s["typical"], "mesh_completeness"), At(none, "mesh_completeness") - 0.005);
    // Points RMS: the bound, 5 % over the clean run at typical; measured +1.0 %
    // (0.0306 against 0.0303 m; +17 % before the near-field test, +39 % before the ghost's rays
    // through the wall were judged; docs/decisions/024-near-field-echoes.md). Light +1.3 %
    // (+16 % before) is held to the same bound; heavy +14 % (+25 % before), held at +20 %.
    EXPECT_LE(At(s["typical"], "points_rms_m"), 1.05 * At(none, "points_rms_m"));
    EXPECT_LE(At(s["light"], "points_rms_m"), 1.05 * At(none, "points_rms_m"));
    EXPECT_LE(At(s["heavy"], "points_rms_m"), 1.20 * At(none, "points_rms_m"));
    if (!HasFailure()) fs::remove_all(dir);
}

// A second seed of the quarry (seed 7: another track over the pit, other episodes): a nadir smile
// over the slope under the shelf (pings 250-260, 8.4 m, beams where the floor is 10-60 % further)
// and a ghost behind the wall whose beams its noise parted into pieces open to each other were
// the excess of the points RMS (+29 %) before the smile test and the enclosed pieces' growth
// across the fan (docs/decisions/025-smile-and-ghost-pieces.md). The bounds at typical,
// but the mesh completeness: -0.53 point of the run without artifacts (-0.71 before the TSDF
// bridged a beam missing in one ping and the floor seen between a school's pings stopped being
// multipath, docs/decisions/026-completeness-beams-the-artifacts-took.md; -0.46 since it bridges
// runs of up to 8 pings where both sides agree, 039-bridging-runs-of-missing-beams.md), held at
// the 0.5 point.
// The same survey without artifacts, less only the beams the artifacts took (rejected by hand,
// nothing else cleaned), is -0.53 point too: that much of the surface no sounding of this
// survey sees, and no cleaning can give it back.
TEST(CleanScenario, ASecondSeedAtTypical) {
    const fs::path dir = FreshDir("pitmap_clean_seed7");
    std::map<std::string, Scores> s;
    for (const std::string level : {"none", "typical"}) {
        s[level] = RunLevel(dir, level, "7");
        ASSERT_FALSE(HasFailure()) << level;
    }
    const Scores& none = s["none"];
    const Scores& typical = s["typical"];
    std::printf(
        "seed 7 typical: artifacts rejected %.4f (smile %.4f, multipath %.4f, bubble %.4f), good "
        "rejected %.4f / %.4f / %.4f, points RMS %.4f m (none %.4f m), mesh mean abs %.4f m "
        "(%.4f m), beyond 1 m %.4f, completeness %.4f (%.4f), DEM mean abs %.4f m (%.4f m)\n",
        At(typical, "artifact_rejected_share"),
        At(typical, "artifact_rejected_share_smile"),
        At(typical, "artifact_rejected_share_multipath"),
        At(typical, "artifact_rejected_share_bubble"),
        At(typical, "good_rejected_share_slope_0_20"),
        At(typical, "good_rejected_share_slope_20_45"),
        At(typical, "good_rejected_share_slope_45_91"),
        At(typical, "points_rms_m"),
        At(none, "points_rms_m"),
        At(typical, "mesh_mean_abs_m"),
        At(none, "mesh_mean_abs_m"),
        At(typical, "mesh_share_beyond_1m"),
        At(typical, "mesh_completeness"),
        At(none, "mesh_completeness"),
        At(typical, "dem_mean_abs_m"),
        At(none, "dem_mean_abs_m"));
    // Measured: artifacts 0.9836 (0.931 before decision 025; smile 0.996, multipath 0.992), good
    // rejected 0.07 / 0.11 / 0.38 %, points RMS +4.0 % (+29 % before), mesh beyond 1 m 0.00 %
    // (0.07 %), mesh mean abs +1.0 %, completeness -0.53 point (-0.71), DEM +0.8 %.
    EXPECT_GE(At(typical, "artifact_rejected_share"), 0.98);
    EXPECT_GE(At(typical, "artifact_rejected_share_smile"), 0.99);
    EXPECT_GE(At(typical, "artifact_rejected_share_multipath"), 0.98);
    for (const std::string level : {"none", "typical"}) {
        for (const char* slope : {"0_20", "20_45", "45_91"}) {
            EXPECT_LE(At(s[level], std::string("good_rejected_share_slope_") + slope), 0.005)
                << level << " slope " << slope;
        }
    }
    EXPECT_LE(At(typical, "points_rms_m"), 1.05 * At(none, "points_rms_m"));
    EXPECT_LE(At(typical, "mesh_share_beyond_1m"), 0.0005);
    EXPECT_LE(At(typical, "mesh_mean_abs_m"), 1.10 * At(none, "mesh_mean_abs_m"));
    EXPECT_GE(At(typical, "mesh_completeness"), At(none, "mesh_completeness") - 0.005);
    EXPECT_LE(At(typical, "dem_mean_abs_m"), 1.15 * At(none, "dem_mean_abs_m"));
    if (!HasFailure()) fs::remove_all(dir);
}

}  // namespace
