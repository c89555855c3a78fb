// SPDX-License-Identifier: MIT
// Scenario test of the backscatter mosaic (issue 17 item 6) against the simulator's ground
// truth: 90 s of the demo survey (the true boresight), whose seabed is 5 m squares of four
// materials (-14, -20, -26, -32 dB) and whose 83P intensities follow the sonar equation (40
// log R spreading, 0.021 dB/m absorption, Lambert's law plus a 6 dB specular lobe, 2 dB
// speckle; truth/backscatter.json). `pitmap run` writes mosaic.tif; pitmap-eval scores it:
//   - the corrected mosaic correlates with the true backscatter and every patch's mean is
//     right within a dB (after the unknown gain is removed);
//   - the uncorrected mosaic (20 log10 intensity) scores clearly worse on every measure;
//   - Lambert's law alone (mosaic.angular: lambert, `pitmap grid` again) leaves the specular
//     lobe: worse than the empirical response;
//   - the same survey in 83P v1.00 (no intensities): no mosaic, said so, no error.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <string>

#include "tests/support/process.hpp"
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

void Print(const char* what, std::map<std::string, double>& s, const std::string& k) {
    std::printf(
        "%-28s correlation %.3f  rms %.2f dB  patch mean |err| %.2f dB  patch max "
        "|err| %.2f dB  level max |err| %.2f dB  (%.0f nodes, %.0f patches)\n",
        what,
        s[k + "correlation"],
        s[k + "rms_db"],
        s[k + "patch_mean_abs_db"],
        s[k + "patch_max_abs_db"],
        s[k + "level_max_abs_db"],
        s[k + "nodes"],
        s[k + "patches"]);
}

TEST(MosaicScenario, CorrectedMosaicMatchesTheSeabedAndBeatsTheUncorrected) {
    const fs::path dir = FreshDir("pitmap_mosaic");
    std::string out;
    ASSERT_EQ(RunCommand(kBin + "/pitmap-sim synth --scenario demo --duration 90 --out " +
                             Quote(dir / "sim"),
                         &out),
              0)
        << out;
    ASSERT_TRUE(SetTrueBoresight(dir / "sim"));
    ASSERT_TRUE(fs::exists(dir / "sim/truth/backscatter.f32"));
    const json truth_model = ReadJson(dir / "sim/truth/backscatter.json");
    EXPECT_EQ(truth_model["spreading_db_per_decade"].get<double>(), 40.0);

    const fs::path P = dir / "p";
    out.clear();
    ASSERT_EQ(RunCommand(kBin + "/pitmap run " + Quote(dir / "sim/log") + " --out " + Quote(P) +
                             " --no-calibrate --no-slam --no-report",
                         &out),
              0)
        << out;
    const json summary = ReadJson(P / "summary.json");
    const json& m = summary["stages"]["grid"]["mosaic"];
    ASSERT_TRUE(m.value("made", false)) << m.dump();
    EXPECT_EQ(m["angular"], "empirical");
    EXPECT_GT(m["used"].get<double>(), 0.9 * m["soundings"].get<double>()) << m.dump();
    ASSERT_TRUE(fs::exists(P / "mosaic.tif"));
    const auto files = summary["stages"]["grid"]["files"];
    EXPECT_NE(std::find(files.begin(), files.end(), "mosaic.tif"), files.end());

    auto s = EvalScores(dir / "sim/truth", P);
    ASSERT_TRUE(s.count("mosaic_correlation")) << "pitmap-eval scored no mosaic";
    ASSERT_TRUE(s.count("mosaic_uncorrected_correlation"));
    Print("corrected (empirical):", s, "mosaic_");
    Print("uncorrected:", s, "mosaic_uncorrected_");
    EXPECT_GT(s["mosaic_nodes"], 5000);
    EXPECT_GE(s["mosaic_patches"], 15);
    // The corrected mosaic: the seabed, patch by patch.
    // (Measured: correlation 0.98, RMS 1.5 dB (2 dB speckle over a few soundings a node),
    // patch mean |error| 0.38 dB, largest 1.3 dB, material means within 0.3 dB.)
    EXPECT_GT(s["mosaic_correlation"], 0.95);
    EXPECT_LT(s["mosaic_rms_db"], 2.0);
    EXPECT_LT(s["mosaic_patch_mean_abs_db"], 0.6);
    EXPECT_LT(s["mosaic_patch_max_abs_db"], 2.0);
    EXPECT_LT(s["mosaic_level_max_abs_db"], 0.6);
    // Without the corrections the range and angle terms (tens of dB) swamp the 18 dB seabed.
    EXPECT_LT(s["mosaic_uncorrected_correlation"], s["mosaic_correlation"] - 0.3);
    EXPECT_GT(s["mosaic_uncorrected_rms_db"], 2.5 * s["mosaic_rms_db"]);
    EXPECT_GT(s["mosaic_uncorrected_patch_mean_abs_db"], 3 * s["mosaic_patch_mean_abs_db"]);

    // Lambert's law alone, on the same survey (the grid stage again).
    std::ofstream(dir / "lambert.yaml") << "mosaic:\n  angular: lambert\n";
    out.clear();
    ASSERT_EQ(RunCommand(kBin + "/pitmap grid --out " + Quote(P) + " --config " +
                             Quote(dir / "lambert.yaml"),
                         &out),
              0)
        << out;
    EXPECT_EQ(ReadJson(P / "summary.json")["stages"]["grid"]["mosaic"]["angular"], "lambert");
    auto l = EvalScores(dir / "sim/truth", P);
    Print("corrected (lambert):", l, "mosaic_");
    // (Measured: RMS 1.8 dB, patch mean |error| 0.65 dB.)
    EXPECT_GT(l["mosaic_rms_db"], s["mosaic_rms_db"] + 0.15);
    EXPECT_GT(l["mosaic_patch_mean_abs_db"], s["mosaic_patch_mean_abs_db"] + 0.15);
    EXPECT_LT(l["mosaic_correlation"], s["mosaic_correlation"]);

    // The report shows it.
    out.clear();
    EXPECT_EQ(RunCommand(kBin + "/pitmap report --out " + Quote(P), &out), 0) << out;
    std::ifstream html(P / "report.html");
    const std::string page((std::istreambuf_iterator<char>(html)),
                           std::istreambuf_iterator<char>());
    EXPECT_NE(page.find("Backscatter mosaic"), std::string::npos);
    EXPECT_NE(page.find("alt=\"Seabed backscatter, corrected"), std::string::npos);

    // 83P v1.00: no intensities. The run goes through; the mosaic says why it is not there.
    out.clear();
    ASSERT_EQ(RunCommand(kBin +
                             "/pitmap-sim synth --scenario demo --duration 20 --sonar-format "
                             "1.00 --out " +
                             Quote(dir / "v100"),
                         &out),
              0)
        << out;
    out.clear();
    ASSERT_EQ(RunCommand(kBin + "/pitmap run " + Quote(dir / "v100/log") + " --out " +
                             Quote(dir / "p100") + " --no-calibrate --no-slam --no-report",
                         &out),
              0)
        << out;
    EXPECT_NE(out.find("no intensities"), std::string::npos) << out;
    const json m100 = ReadJson(dir / "p100/summary.json")["stages"]["grid"]["mosaic"];
    EXPECT_FALSE(m100.value("made", true));
    EXPECT_NE(m100.value("reason", "").find("no intensities"), std::string::npos);
    EXPECT_FALSE(fs::exists(dir / "p100/mosaic.tif"));
    if (!HasFailure()) fs::remove_all(dir);
}

}  // namespace
