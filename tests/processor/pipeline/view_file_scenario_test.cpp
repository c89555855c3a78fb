// SPDX-License-Identifier: MIT
// Scenario test of the georeferenced view living in its scratch file from the moment it is made
// (issue 38, docs/decisions/033-view-written-by-blocks.md): bejanca georeferenced and
// calibrated twice with `pitmap georef` and `pitmap calibrate`, once with blocks of 1 024
// soundings (the view written, read by the calibration, re-georeferenced and read by the point
// writers in about a thousand blocks) and once with one block holding the whole view. The
// point files, boresight.json and the stages' figures are the same, byte for byte but for the
// run id and the processing time; georef says the view went to its file, and no scratch file
// stays.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "tests/support/process.hpp"
#include "tests/support/scenario.hpp"

namespace {

namespace fs = std::filesystem;
using pitmap::test::kBin;
using pitmap::test::Quote;
using pitmap::test::ReadJson;
using pitmap::test::RunCommand;

// Zeroes every occurrence of `what` in `b`.
void Mask(std::string& b, const std::string& what) {
    if (what.empty()) return;
    for (std::size_t at = b.find(what); at != std::string::npos; at = b.find(what, at + 1)) {
        for (std::size_t k = 0; k < what.size(); ++k) b[at + k] = '0';
    }
}

// A product's bytes without what two georeferences of one log do not share: the run id (as
// text, and as LAS's 16-byte project GUID) and every UTC time (YYYY-MM-DDTHH:MM:SSZ).
std::string Bytes(const fs::path& p, const std::string& run_id) {
    std::ifstream in(p, std::ios::binary);
    std::string b{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
    Mask(b, run_id);
    std::string guid;
    for (std::size_t i = 0; i + 1 < run_id.size(); i += 2)
        guid.push_back(static_cast<char>(std::stoi(run_id.substr(i, 2), nullptr, 16)));
    if (guid.size() == 16) Mask(b, guid);
    pitmap::test::ZeroUtcTimes(b);
    return b;
}

// A stage's record in summary.json without what differs between two runs of one build.
nlohmann::json Figures(const fs::path& summary, const char* stage) {
    nlohmann::json g = ReadJson(summary)["stages"][stage];
    for (const char* k : {"peak_rss_mb", "seconds", "cpu_seconds", "started_utc", "finished_utc"})
        g.erase(k);
    return g;
}

const char* const kProducts[] = {"points.ply", "points.las", "points_utm.ply", "boresight.json"};

TEST(ViewFileScenario, TheViewInItsFileByBlocksGivesTheOneBlockProducts) {
    const fs::path dir = pitmap::test::FreshDir("pitmap_view_file_scenario");
    std::string out;
    ASSERT_EQ(RunCommand(kBin +
                             "/pitmap-sim synth --scenario bejanca --duration 240 "
                             "--echo-artifacts typical --out " +
                             Quote(dir / "sim"),
                         &out),
              0)
        << out;
    const fs::path small = dir / "small", whole = dir / "whole";
    std::ofstream(dir / "small.yaml") << "run:\n  block_soundings: 1024\n";
    std::ofstream(dir / "whole.yaml") << "run:\n  block_soundings: 100000000\n"
                                      << "  memory_budget_mb: 100000\n";
    for (const fs::path& p : {small, whole}) {
        const fs::path config = dir / (p.filename().string() + ".yaml");
        ASSERT_EQ(RunCommand(kBin + "/pitmap georef " + Quote(dir / "sim/log") + " --out " +
                                 Quote(p) + " --config " + Quote(config),
                             &out),
                  0)
            << out;
        EXPECT_TRUE(ReadJson(p / "summary.json")["stages"]["georef"].value("view_in_file", false))
            << p;
        EXPECT_FALSE(fs::exists(p / ".partial-view_points")) << p;
    }
    const std::string id_small = ReadJson(small / "summary.json").value("run_id", "");
    const std::string id_whole = ReadJson(whole / "summary.json").value("run_id", "");
    ASSERT_EQ(id_small.size(), 32u);
    ASSERT_GT(ReadJson(small / "summary.json")["soundings"].value("accepted", 0), 1000 * 1024)
        << "too few soundings for many blocks";
    EXPECT_EQ(Figures(small / "summary.json", "georef"), Figures(whole / "summary.json", "georef"));
    EXPECT_EQ(ReadJson(small / "summary.json")["mount_check"],
              ReadJson(whole / "summary.json")["mount_check"]);
    for (const char* f : kProducts) {
        if (!fs::exists(whole / f)) continue;
        EXPECT_TRUE(Bytes(small / f, id_small) == Bytes(whole / f, id_whole)) << "georef: " << f;
    }

    for (const fs::path& p : {small, whole}) {
        const fs::path config = dir / (p.filename().string() + ".yaml");
        ASSERT_EQ(
            RunCommand(kBin + "/pitmap calibrate --out " + Quote(p) + " --config " + Quote(config),
                       &out),
            0)
            << out;
        EXPECT_FALSE(fs::exists(p / ".partial-view_points")) << p;
        EXPECT_FALSE(fs::exists(p / ".partial-view_points-next")) << p;
    }
    const nlohmann::json cal = Figures(small / "summary.json", "calibrate");
    ASSERT_TRUE(cal.is_object());
    EXPECT_EQ(cal, Figures(whole / "summary.json", "calibrate")) << cal.dump(1);
    EXPECT_EQ(ReadJson(small / "summary.json")["soundings"],
              ReadJson(whole / "summary.json")["soundings"]);
    for (const char* f : kProducts) {
        ASSERT_TRUE(fs::exists(small / f)) << f;
        EXPECT_TRUE(Bytes(small / f, id_small) == Bytes(whole / f, id_whole)) << "calibrate: " << f;
    }
}

}  // namespace
