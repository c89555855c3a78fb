// SPDX-License-Identifier: MIT
// Scenario test of the grid stage reading the georeferenced view a block at a time from its
// scratch file (issue 38 item 1, docs/decisions/031-grid-stage-by-view-blocks.md) and running
// CUBE and its surface filter by bands of node rows from CUBE's input on disk (decision 035):
// the first 90 s of bejanca, georeferenced once, gridded twice from copies of one products
// folder, with blocks of 1 024 soundings (the smallest; about 400 blocks, CUBE in bands of at
// most 4 096 soundings) and with one block holding the whole view (CUBE in one band). The DEM
// (every band, bit for bit), the point files, S-44's holiday map and the layers made from the
// DEM (byte for byte, the processing time masked), the survey model's flags and summary.json's
// figures (the TPU, the sound speed, S-44, CUBE, the surface filter's rejections, the
// soundings' counts) are the same, and no scratch file is left.
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "processor/io/grid_io.hpp"
#include "tests/support/process.hpp"
#include "tests/support/scenario.hpp"

namespace {

namespace fs = std::filesystem;
using pitmap::test::BytesWithoutUtcTimes;
using pitmap::test::kBin;
using pitmap::test::Quote;
using pitmap::test::ReadJson;
using pitmap::test::RunCommand;

// summary.json's grid record without what differs between two runs of one build (times,
// memory, the run's own clock).
nlohmann::json GridFigures(const fs::path& summary) {
    nlohmann::json g = ReadJson(summary)["stages"]["grid"];
    for (const char* k : {"timings_wall_cpu_s",
                          "peak_rss_mb_by_part",
                          "peak_rss_mb",
                          "wall_s",
                          "cpu_s",
                          "seconds",
                          "cpu_seconds",
                          "started_utc",
                          "finished_utc",
                          "cube_bands"}) {
        g.erase(k);
    }
    return g;
}

TEST(GridBlocksScenario, BlocksOfTheSpilledViewGiveTheWholeViewsProducts) {
    const fs::path dir = pitmap::test::FreshDir("pitmap_grid_blocks_scenario");
    std::string out;
    ASSERT_EQ(RunCommand(kBin +
                             "/pitmap-sim synth --scenario bejanca --duration 90 "
                             "--echo-artifacts typical --out " +
                             Quote(dir / "sim"),
                         &out),
              0)
        << out;
    const fs::path small = dir / "small", whole = dir / "whole";
    ASSERT_EQ(
        RunCommand(kBin + "/pitmap georef " + Quote(dir / "sim/log") + " --out " + Quote(small),
                   &out),
        0)
        << out;
    fs::copy(small, whole, fs::copy_options::recursive);
    std::ofstream(dir / "small.yaml") << "run:\n  block_soundings: 1024\n";
    std::ofstream(dir / "whole.yaml") << "run:\n  block_soundings: 100000000\n"
                                      << "  memory_budget_mb: 100000\n";
    for (const fs::path& p : {small, whole}) {
        const fs::path config = dir / (p.filename().string() + ".yaml");
        ASSERT_EQ(RunCommand(kBin + "/pitmap grid --out " + Quote(p) + " --config " + Quote(config),
                             &out),
                  0)
            << out;
        for (const auto& e : fs::directory_iterator(p)) {
            EXPECT_NE(e.path().filename().string().rfind(".partial-", 0), 0U) << e.path();
        }
    }
    // CUBE by many bands with the small blocks, by one with the whole view.
    EXPECT_GT(ReadJson(small / "summary.json")["stages"]["grid"].value("cube_bands", 0), 4);
    EXPECT_EQ(ReadJson(whole / "summary.json")["stages"]["grid"].value("cube_bands", 0), 1);
    const nlohmann::json a = GridFigures(small / "summary.json");
    const nlohmann::json b = GridFigures(whole / "summary.json");
    ASSERT_GT(a.value("soundings", 0), 100 * 1024) << "too few soundings for many blocks";
    EXPECT_GT(a.value("surface_filter_rejected", 0), 0) << "the filter's verdicts not exercised";
    EXPECT_EQ(a, b) << a.dump(1) << "\n" << b.dump(1);
    EXPECT_EQ(ReadJson(small / "summary.json")["soundings"],
              ReadJson(whole / "summary.json")["soundings"]);

    // The DEM, every band bit for bit.
    auto da = pitmap::proc::io::ReadGrid((small / "dem.tif").string());
    auto db = pitmap::proc::io::ReadGrid((whole / "dem.tif").string());
    ASSERT_TRUE(da && db);
    ASSERT_EQ(da->grid.layers.size(), db->grid.layers.size());
    for (std::size_t l = 0; l < da->grid.layers.size(); ++l) {
        const auto& x = da->grid.layers[l].values;
        const auto& y = db->grid.layers[l].values;
        ASSERT_EQ(x.size(), y.size());
        EXPECT_EQ(0, std::memcmp(x.data(), y.data(), x.size() * sizeof(float)))
            << da->grid.layers[l].name;
    }
    // The files the blocks feed, byte for byte but for the processing time.
    for (const char* f : {"points.ply",
                          "points.las",
                          "points_utm.ply",
                          "soundings_tpu.ply",
                          "s44_holidays.tif",
                          "dem.tif",
                          "mosaic.tif",
                          "terrain.tif",
                          "crawler.tif",
                          "capacity.csv",
                          "survey.pitmap"}) {
        if (!fs::exists(whole / f)) continue;
        EXPECT_TRUE(BytesWithoutUtcTimes(small / f) == BytesWithoutUtcTimes(whole / f)) << f;
    }
}

}  // namespace
