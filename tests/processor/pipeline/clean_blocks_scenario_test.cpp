// SPDX-License-Identifier: MIT
// Scenario test of the clean stage reading the georeferenced view a block at a time from its
// scratch file (issue 38, docs/decisions/037-clean-stage-by-view-blocks.md): the first 90 s of
// bejanca with typical echo artifacts (schools, bubbles, the smile, multipath), georeferenced
// once, cleaned twice from copies of one products folder, with blocks of 1 024 soundings (the
// smallest: about 400 blocks, a few pings each, and the plane fits in batches of 8 of them) and
// with one block holding the whole view. Every sounding's verdict and reason (the survey model's
// flags: survey.pitmap byte for byte), the point files and summary.json's figures of the
// cleaning are the same.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
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

// summary.json's clean record without what differs between two runs (times, memory, blocks).
nlohmann::json CleanFigures(const fs::path& summary) {
    nlohmann::json c = ReadJson(summary)["stages"]["clean"];
    for (auto it = c.begin(); it != c.end();) {
        const std::string& k = it.key();
        const bool varies = k.rfind("seconds", 0) == 0 || k.rfind("cpu_", 0) == 0 ||
                            k.rfind("peak_rss_mb", 0) == 0 || k.rfind("wall_", 0) == 0 ||
                            k == "block_soundings" || k == "started_utc" || k == "finished_utc" ||
                            k == "run_id";
        it = varies ? c.erase(it) : std::next(it);
    }
    return c;
}

TEST(CleanBlocksScenario, BlocksOfTheSpilledViewGiveTheWholeViewsVerdicts) {
    const fs::path dir = pitmap::test::FreshDir("pitmap_clean_blocks_scenario");
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
        ASSERT_EQ(
            RunCommand(kBin + "/pitmap clean --out " + Quote(p) + " --config " + Quote(config),
                       &out),
            0)
            << out;
        EXPECT_FALSE(fs::exists(p / ".partial-view_points")) << p;
    }
    const nlohmann::json a = CleanFigures(small / "summary.json");
    const nlohmann::json b = CleanFigures(whole / "summary.json");
    ASSERT_GT(a.value("soundings", 0), 100 * 1024) << "too few soundings for many blocks";
    EXPECT_EQ(ReadJson(small / "summary.json")["stages"]["clean"].value("block_soundings", 0),
              1024);
    // The echo artifacts exercise the 3D tests and the profiles.
    EXPECT_GT(a.value("free_space", 0) + a.value("cluster", 0) + a.value("multipath", 0), 0);
    EXPECT_GT(a.value("profile", 0), 0);
    EXPECT_EQ(a, b) << a.dump(1) << "\n" << b.dump(1);
    EXPECT_EQ(ReadJson(small / "summary.json")["soundings"],
              ReadJson(whole / "summary.json")["soundings"]);
    // Every sounding's flag and reason (the model's flags), and the soundings kept.
    for (const char* f : {"survey.pitmap", "points.ply"}) {
        ASSERT_TRUE(fs::exists(whole / f)) << f;
        EXPECT_TRUE(BytesWithoutUtcTimes(small / f) == BytesWithoutUtcTimes(whole / f)) << f;
    }
}

}  // namespace
