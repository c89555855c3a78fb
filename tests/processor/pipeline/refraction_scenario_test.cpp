// SPDX-License-Identifier: MIT
// Scenario test of refraction (issue 17 item 1), scored against ground truth with pitmap-eval:
// a short demo survey simulated twice with the same seed, once in a homogeneous water column
// and once through a warm mixed layer over a thermocline (pitmap-sim --refraction). Both are
// georeferenced with the true boresight:
//   - the refracting survey with straight rays: its error at the outer beams (55-60 deg) is
//     reported and must be clearly above the homogeneous survey's;
//   - the refracting survey ray traced through the simulator's cast (truth/water_column.svp,
//     CARIS .svp): points RMS within 5 % of the homogeneous survey's.
// A malformed cast stops `pitmap georef` with an error naming the file and line.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "tests/support/scenario.hpp"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

using pitmap::test::EvalScores;
using pitmap::test::FreshDir;
using pitmap::test::kBin;
using pitmap::test::Quote;
using pitmap::test::ReadJson;
using pitmap::test::RunCommand;
using pitmap::test::SetTrueBoresight;

TEST(RefractionScenario, RayTracingRecoversTheHomogeneousSurveysAccuracy) {
    const fs::path dir = FreshDir("pitmap_refraction");
    std::string out;
    const std::string synth = kBin + "/pitmap-sim synth --scenario demo --duration 60 --out ";
    ASSERT_EQ(RunCommand(synth + Quote(dir / "flat"), &out), 0) << out;
    ASSERT_EQ(RunCommand(synth + Quote(dir / "refr") + " --refraction --vendor-files", &out), 0)
        << out;
    ASSERT_TRUE(fs::exists(dir / "refr/truth/water_column.svp"));
    ASSERT_TRUE(fs::exists(dir / "refr/vendor/demo.svp"));
    ASSERT_TRUE(SetTrueBoresight(dir / "flat"));
    ASSERT_TRUE(SetTrueBoresight(dir / "refr"));

    const auto georef_eval = [&](const fs::path& sim,
                                 const std::string& name,
                                 const std::string& extra) {
        const fs::path p = dir / name;
        std::string text;
        EXPECT_EQ(
            RunCommand(kBin + "/pitmap georef " + Quote(sim / "log") + " --out " + Quote(p) + extra,
                       &text),
            0)
            << text;
        return EvalScores(sim / "truth", p);
    };
    const auto flat = georef_eval(dir / "flat", "p_flat", "");
    const auto straight = georef_eval(dir / "refr", "p_straight", "");
    const auto traced = georef_eval(
        dir / "refr", "p_traced", " --svp " + Quote(dir / "refr/truth/water_column.svp"));
    for (const auto* s : {&flat, &straight, &traced}) {
        ASSERT_TRUE(s->count("points_rms_m") && s->count("points_rms_m_angle_55_90"))
            << "pitmap-eval printed no points_rms_m / points_rms_m_angle_55_90";
    }
    const double outer_flat = flat.at("points_rms_m_angle_55_90");
    const double outer_straight = straight.at("points_rms_m_angle_55_90");
    const double outer_traced = traced.at("points_rms_m_angle_55_90");
    RecordProperty("points_rms_m_flat", std::to_string(flat.at("points_rms_m")));
    RecordProperty("points_rms_m_straight", std::to_string(straight.at("points_rms_m")));
    RecordProperty("points_rms_m_traced", std::to_string(traced.at("points_rms_m")));
    RecordProperty("outer_beams_rms_m_flat", std::to_string(outer_flat));
    RecordProperty("outer_beams_rms_m_straight", std::to_string(outer_straight));
    RecordProperty("outer_beams_rms_m_traced", std::to_string(outer_traced));
    std::printf(
        "points RMS (m): homogeneous %.4f, refracting straight %.4f, ray traced %.4f\n"
        "55-60 deg beams RMS (m): homogeneous %.4f, straight %.4f, ray traced %.4f\n",
        flat.at("points_rms_m"),
        straight.at("points_rms_m"),
        traced.at("points_rms_m"),
        outer_flat,
        outer_straight,
        outer_traced);
    // Straight rays through the thermocline are measurably wrong at the outer beams ...
    EXPECT_GT(outer_straight, 2.0 * outer_flat);
    EXPECT_GT(straight.at("points_rms_m"), 1.5 * flat.at("points_rms_m"));
    // ... and ray tracing brings the survey back to the homogeneous one's accuracy.
    EXPECT_LT(traced.at("points_rms_m"), 1.05 * flat.at("points_rms_m"));
    EXPECT_LT(outer_traced, 1.05 * outer_flat);
    EXPECT_GT(traced.at("points_scored"), 0.97 * flat.at("points_scored"));
    const json summary = ReadJson(dir / "p_traced/summary.json");
    ASSERT_TRUE(summary.contains("refraction"));
    EXPECT_EQ(summary["refraction"]["casts"].size(), 1u);
    // The cast's profile, for the report's speed-against-depth plot: all its points (fewer
    // than the 200 kept), surface first.
    const json& cast = summary["refraction"]["casts"][0];
    ASSERT_TRUE(cast.contains("profile")) << cast.dump();
    EXPECT_EQ(cast["profile"]["depth_m"].size(), cast["points"].get<std::size_t>());
    EXPECT_EQ(cast["profile"]["speed_mps"].size(), cast["points"].get<std::size_t>());
    EXPECT_EQ(cast["profile"]["speed_mps"][0].get<double>(),
              cast["surface_speed_mps"].get<double>());
    EXPECT_EQ(cast["profile"]["depth_m"].back().get<double>(), cast["max_depth_m"].get<double>());
    EXPECT_EQ(summary["stages"]["georef"]["refraction_failed"].get<int>(), 0);

    // A bad cast: a clear error naming the file and the line, before any ingest.
    const fs::path bad = dir / "bad.svp";
    std::ofstream(bad) << "0 1496\n3 1490\n3 1480\n";
    std::string text;
    EXPECT_NE(RunCommand(kBin + "/pitmap georef " + Quote(dir / "refr/log") + " --out " +
                             Quote(dir / "p_bad") + " --svp " + Quote(bad),
                         &text),
              0);
    EXPECT_NE(text.find(bad.string() + ":3: depth 3.000 m is not below the previous depth"),
              std::string::npos)
        << text;
    if (!HasFailure()) fs::remove_all(dir);
}

}  // namespace
