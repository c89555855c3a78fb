// SPDX-License-Identifier: MIT
// Scenario test of the vertical datum and IHO S-44 quality control (issue 17 items 2 and 5),
// against the simulator's ground truth: 90 s of the demo survey (a pit 4 m deep, the INS on
// the water line, true boresight) simulated twice with the same seed, once with a patch of
// bottom 2 m in radius that returns nothing (pitmap-sim --dropout-patch: a holiday made on
// purpose). `pitmap run` with the water-level datum from the GNSS heights and order 1a:
//   - the datum is the true water surface (412.0 m above the ellipsoid) within 5 cm;
//   - the soundings meet order 1a's TVU and THU (a known survey with 2 cm + 0.2 % range noise
//     and RTK: all of them), and points.las / points.ply carry THU/TVU;
//   - the survey without the patch has no holiday; with it, exactly one, centred within
//     0.5 m of the patch and of about its area (the capture distance closes its rim);
//   - the track crosses its own earlier lines and, with the true boresight, the crossing
//     soundings agree within the TVU limit;
//   - pitmap-eval still reads points.ply (extra properties), and the report has the section.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "tests/support/scenario.hpp"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

using pitmap::test::FreshDir;
using pitmap::test::kBin;
using pitmap::test::Quote;
using pitmap::test::ReadJson;
using pitmap::test::RunCommand;
using pitmap::test::Scores;
using pitmap::test::SetTrueBoresight;

TEST(S44Scenario, WaterLevelDatumComplianceHolidayAndCrosslines) {
    const fs::path dir = FreshDir("pitmap_s44");
    std::string out;
    // The patch, in the simulator's world frame (pit centre on the water surface).
    const double px = -2.0, py = 0.0, pr = 2.0;
    const std::string synth = kBin + "/pitmap-sim synth --scenario demo --duration 90 --out ";
    ASSERT_EQ(RunCommand(synth + Quote(dir / "clean"), &out), 0) << out;
    ASSERT_EQ(RunCommand(synth + Quote(dir / "patch") + " --dropout-patch -2 0 2", &out), 0) << out;
    ASSERT_TRUE(SetTrueBoresight(dir / "clean"));
    ASSERT_TRUE(SetTrueBoresight(dir / "patch"));
    std::ofstream(dir / "hydro.yaml") << "vertical:\n  datum: water_level\ns44:\n  order: 1a\n";

    const auto run = [&](const std::string& name) {
        std::string text;
        EXPECT_EQ(
            RunCommand(kBin + "/pitmap run " + Quote(dir / name / "log") + " --out " +
                           Quote(dir / ("p_" + name)) + " --config " + Quote(dir / "hydro.yaml") +
                           " --no-calibrate --no-slam --no-report",
                       &text),
            0)
            << text;
        return ReadJson(dir / ("p_" + name) / "summary.json");
    };
    const json clean = run("clean");
    const json patch = run("patch");
    for (const json* s : {&clean, &patch}) {
        ASSERT_TRUE(s->contains("vertical_datum"));
        ASSERT_TRUE((*s)["stages"]["grid"].contains("s44"));
    }

    // The datum: the water surface the simulator made (its world origin's height).
    const json truth = ReadJson(dir / "patch/truth/terrain.json");
    const json& vd = patch["vertical_datum"];
    EXPECT_EQ(vd["datum"], "water_level");
    EXPECT_EQ(vd["vertical_crs"], "pit water level (GNSS, survey median)");
    EXPECT_NEAR(
        vd["mean_datum_height_m"].get<double>(), truth["origin"]["height_m"].get<double>(), 0.05);

    // Order 1a on a known survey: every sounding within its TVU and THU limits.
    const json& q = patch["stages"]["grid"]["s44"];
    EXPECT_EQ(q["order"], "1a");
    EXPECT_GT(q["soundings"].get<double>(), 100000);
    EXPECT_GT(q["soundings_within_tvu"]["1a"].get<double>(), 0.99);
    EXPECT_GT(q["soundings_within_thu"]["1a"].get<double>(), 0.99);
    EXPECT_GT(q["nodes_within_tvu"]["1a"].get<double>(), 0.99);
    // Every node's THU from the soundings CUBE offered it (issue 39: was 0.89 for every order).
    EXPECT_GT(q["nodes_within_thu"]["1a"].get<double>(), 0.99);
    EXPECT_EQ(q["nodes_without_thu"].get<int>(), 0);
    EXPECT_FALSE(q["strictest_order_met_95"].is_null());
    const auto files = patch["stages"]["grid"]["files"];
    for (const char* f : {"points.ply", "points.las", "s44_holidays.tif", "dem.tif"}) {
        EXPECT_NE(std::find(files.begin(), files.end(), f), files.end()) << f;
        EXPECT_TRUE(fs::exists(dir / "p_patch" / f)) << f;
    }

    // Holidays: none in the clean survey, the one made on purpose where it was made.
    EXPECT_EQ(clean["stages"]["grid"]["s44"]["holiday_count"].get<int>(), 0)
        << clean["stages"]["grid"]["s44"]["holidays"].dump();
    ASSERT_EQ(q["holiday_count"].get<int>(), 1) << q["holidays"].dump();
    const json& h = q["holidays"][0];
    // pitmap's world origin is the first INS fix; the simulator's is the pit centre.
    const json& wo = patch["world_origin"];
    const double lat0 = truth["origin"]["latitude_deg"].get<double>() * M_PI / 180;
    const double de =
        (wo["longitude_deg"].get<double>() - truth["origin"]["longitude_deg"].get<double>()) *
        M_PI / 180 * 6378137.0 * std::cos(lat0);
    const double dn =
        (wo["latitude_deg"].get<double>() - truth["origin"]["latitude_deg"].get<double>()) * M_PI /
        180 * 6371000.0;
    const double hx = h["world_m"][0].get<double>() + de;
    const double hy = h["world_m"][1].get<double>() + dn;
    std::printf("holiday at (%.2f, %.2f) m (patch at (%.1f, %.1f)), %.2f m2, square %.2f m\n",
                hx,
                hy,
                px,
                py,
                h["area_m2"].get<double>(),
                h["largest_square_m"].get<double>());
    EXPECT_LT(std::hypot(hx - px, hy - py), 0.5);
    EXPECT_GT(h["area_m2"].get<double>(), 0.5 * M_PI * pr * pr);
    EXPECT_LT(h["area_m2"].get<double>(), 1.05 * M_PI * pr * pr);
    EXPECT_GE(h["largest_square_m"].get<double>(), 2.0);  // order 1a's feature

    // Crosslines: the circling track crosses its earlier lines; with the true boresight they
    // agree (mean near 0, nearly all within order 1a's TVU).
    const json& cl = q["crossline"];
    EXPECT_GT(cl["compared"].get<double>(), 5000);
    EXPECT_LT(std::abs(cl["mean_m"].get<double>()), 0.05);
    EXPECT_GT(cl["within_tvu"].get<double>(), 0.97);
    EXPECT_GE(cl["by_angle"].size(), 4u);
    std::printf("crossline: %.0f compared, mean %.4f m, RMS %.4f m, within TVU %.3f\n",
                cl["compared"].get<double>(),
                cl["mean_m"].get<double>(),
                cl["rms_m"].get<double>(),
                cl["within_tvu"].get<double>());

    // pitmap-eval still reads points.ply; the report has the section.
    std::string text;
    EXPECT_EQ(RunCommand(kBin + "/pitmap-eval --truth " + Quote(dir / "patch/truth") +
                             " --products " + Quote(dir / "p_patch"),
                         &text),
              0)
        << text;
    EXPECT_LT(Scores(text).at("points_rms_m"), 0.1) << text;
    // The DEM is in the water-level datum: pitmap-eval adds the datum height back before it
    // scores against the ellipsoidal truth (without it the error would be the ~412 m datum).
    ASSERT_TRUE(Scores(text).count("dem_mean_abs_m")) << text;
    EXPECT_LT(Scores(text).at("dem_mean_abs_m"), 0.05) << text;
    text.clear();
    EXPECT_EQ(RunCommand(kBin + "/pitmap report --out " + Quote(dir / "p_patch"), &text), 0)
        << text;
    std::ifstream html(dir / "p_patch/report.html");
    const std::string page((std::istreambuf_iterator<char>(html)),
                           std::istreambuf_iterator<char>());
    EXPECT_NE(page.find("IHO S-44 Edition 6.1: order 1a"), std::string::npos);
    EXPECT_NE(page.find("pit water level (GNSS, survey median)"), std::string::npos);
    if (!HasFailure()) fs::remove_all(dir);
}

}  // namespace
