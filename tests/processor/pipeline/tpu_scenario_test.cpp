// SPDX-License-Identifier: MIT
// Scenario test of the TPU's calibration against ground truth (issue 36 items 2 and 3): the
// quarry (210 s; its first 120 s overlap too little for the calibration without a cast) in a
// refracting water column (pitmap-sim --refraction: a warm mixed
// layer over a thermocline), processed by `pitmap run` with the simulator's cast and without
// any cast, scored with pitmap-eval (the true beams cast along the curved rays):
//   - with the cast, 93-97 % of the soundings lie within their 95 % TVU in each beam-angle
//     class (0-20, 20-40, 40-60 deg), and the DEM nodes on floors and faces within their 95 %
//     uncertainty (>= 93 %); the shares measured are in docs/uncertainty.md;
//   - without a cast the swath overlap shows the stratified column, the TPU takes the
//     a-priori bound and says so (gate grid/sound_speed_not_assessable), and >= 90 % of the
//     soundings lie within their TVU (the bound; 98.2 % measured with the column
//     term's swath-common part, docs/decisions/019; 89.0 % before it).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
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

bool Tripped(const json& summary, const std::string& gate) {
    if (!summary.contains("quality_gates")) return false;
    for (const json& g : summary["quality_gates"]) {
        if (g.value("gate", std::string()) == gate) return true;
    }
    return false;
}

TEST(TpuScenario, RefractingQuarryWithAndWithoutACast) {
    const fs::path dir = FreshDir("pitmap_tpu");
    std::string out;
    ASSERT_EQ(RunCommand(kBin + "/pitmap-sim synth --scenario quarry --refraction --out " +
                             Quote(dir / "sim"),
                         &out),
              0)
        << out;
    std::ofstream(dir / "tpu.yaml") << "grid:\n  write_sounding_tpu: true\n";
    const auto run = [&](const std::string& name, const std::string& extra) {
        std::string text;
        EXPECT_EQ(RunCommand(kBin + "/pitmap run " + Quote(dir / "sim/log") + " --out " +
                                 Quote(dir / name) + " --no-report --config " +
                                 Quote(dir / "tpu.yaml") + extra,
                             &text),
                  0)
            << text;
        return EvalScores(dir / "sim/truth", dir / name);
    };
    const auto cast = run("p_cast", " --svp " + Quote(dir / "sim/truth/water_column.svp"));
    const auto none = run("p_none", "");
    for (const char* c : {"angle_00_20", "angle_20_40", "angle_40_60"}) {
        const std::string k = std::string("tpu_within_tvu_") + c;
        ASSERT_TRUE(cast.count(k) && none.count(k)) << k;
        RecordProperty(k + "_cast", std::to_string(cast.at(k)));
        RecordProperty(k + "_no_cast", std::to_string(none.at(k)));
        EXPECT_GE(cast.at(k), 0.93) << k;
        EXPECT_LE(cast.at(k), 0.975) << k;
    }
    for (const char* k :
         {"dem_within_uncertainty_slope_00_20", "dem_within_uncertainty_slope_20_45"}) {
        ASSERT_TRUE(cast.count(k)) << k;
        RecordProperty(std::string(k) + "_cast", std::to_string(cast.at(k)));
        EXPECT_GE(cast.at(k), 0.93) << k;
    }
    const json with = ReadJson(dir / "p_cast/summary.json");
    EXPECT_EQ(with["stages"]["grid"]["sound_speed"]["source"].get<std::string>(), "cast+overlap");
    EXPECT_FALSE(with["stages"]["grid"]["sound_speed"]["stratified"].get<bool>());
    EXPECT_FALSE(Tripped(with, "sound_speed_not_assessable"));

    // Without a cast: honest, and flagged.
    ASSERT_TRUE(none.count("tpu_within_tvu"));
    RecordProperty("tpu_within_tvu_no_cast", std::to_string(none.at("tpu_within_tvu")));
    // The issue: >= 90 % within, or a clear flag; both are required (docs/decisions/019), and
    // the 90 % in every beam-angle class (near 45 deg the per-angle column term vanishes).
    EXPECT_GE(none.at("tpu_within_tvu"), 0.90);
    for (const char* c : {"angle_00_20", "angle_20_40", "angle_40_60"}) {
        EXPECT_GE(none.at(std::string("tpu_within_tvu_") + c), 0.90) << c << " without a cast";
    }
    const json without = ReadJson(dir / "p_none/summary.json");
    EXPECT_EQ(without["stages"]["grid"]["sound_speed"]["source"].get<std::string>(),
              "a_priori_bound");
    EXPECT_TRUE(without["stages"]["grid"]["sound_speed"]["stratified"].get<bool>());
    EXPECT_TRUE(Tripped(without, "sound_speed_not_assessable"));
    if (!HasFailure()) fs::remove_all(dir);
}

}  // namespace
