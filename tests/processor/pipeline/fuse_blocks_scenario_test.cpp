// SPDX-License-Identifier: MIT
// Scenario test of the TSDF stage reading the georeferenced view a block at a time from its
// scratch file (issue 38, docs/decisions/034-tsdf-by-view-blocks.md): the first 90 s of bejanca,
// georeferenced once, fused and meshed twice from copies of one products folder, with blocks of
// 1 024 soundings (about two pings each: pings cut by the blocks' edges, two batches of scans
// with their neighbours carried across) and with one block holding the whole view. tsdf.vdb
// (voxel for voxel, and byte for byte), the mesh files (byte for byte, the processing time
// masked) and summary.json's integration counts are the same.
#include <gtest/gtest.h>

#include <array>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <string>
#include <utility>

#include "processor/fusion/vdb_io.hpp"
#include "tests/support/process.hpp"
#include "tests/support/scenario.hpp"

namespace {

namespace fs = std::filesystem;
using pitmap::test::BytesWithoutUtcTimes;
using pitmap::test::kBin;
using pitmap::test::Quote;
using pitmap::test::ReadJson;
using pitmap::test::RunCommand;

std::map<std::array<int, 3>, std::pair<float, float>> Voxels(const fs::path& vdb) {
    std::map<std::array<int, 3>, std::pair<float, float>> out;
    auto v = pitmap::proc::fusion::ReadVdb(vdb.string());
    if (!v) {
        ADD_FAILURE() << v.error().message;
        return out;
    }
    v->ForEachVoxel([&](const Eigen::Vector3i& ijk, float d, float w) {
        out[{ijk.x(), ijk.y(), ijk.z()}] = {d, w};
    });
    return out;
}

TEST(FuseBlocksScenario, BlocksOfTheSpilledViewGiveTheWholeViewsVolumeAndMesh) {
    const fs::path dir = pitmap::test::FreshDir("pitmap_fuse_blocks_scenario");
    std::string out;
    ASSERT_EQ(RunCommand(kBin + "/pitmap-sim synth --scenario bejanca --duration 90 --out " +
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
        const std::string config = " --config " + Quote(dir / (p.filename().string() + ".yaml"));
        ASSERT_EQ(RunCommand(kBin + "/pitmap fuse --out " + Quote(p) + config, &out), 0) << out;
        ASSERT_EQ(RunCommand(kBin + "/pitmap mesh --out " + Quote(p) + config, &out), 0) << out;
        EXPECT_FALSE(fs::exists(p / ".partial-view_points")) << p;
    }
    const nlohmann::json a = ReadJson(small / "summary.json")["stages"]["fuse"];
    const nlohmann::json b = ReadJson(whole / "summary.json")["stages"]["fuse"];
    // The small blocks did cut the survey: many blocks of the view, more than one batch of scans.
    EXPECT_EQ(a.value("view_block_soundings", 0), 1024);
    EXPECT_GT(a.value("scan_batches", nlohmann::json::object()).value("calls", 0), 1);
    EXPECT_EQ(b.value("scan_batches", nlohmann::json::object()).value("calls", 0), 1);
    EXPECT_GT(a.value("beams_used", 0), 100 * 1024);
    for (const char* k : {"scans",
                          "beams_used",
                          "beams_no_detection",
                          "beams_out_of_range",
                          "beams_inconsistent",
                          "voxel_updates",
                          "active_voxels",
                          "voxels_before_filter",
                          "voxels_removed"}) {
        EXPECT_EQ(a.value(k, -1), b.value(k, -2)) << k;
    }
    const auto va = Voxels(small / "tsdf.vdb");
    EXPECT_GT(va.size(), 100000u);
    EXPECT_TRUE(va == Voxels(whole / "tsdf.vdb"));
    // tsdf.vdb byte for byte but for the UUID OpenVDB's header gives each file it writes (36
    // characters after the magic, the file and library versions and a flag: bytes 21 to 56) and
    // the trailer's CRC over the file (the 4 bytes before the trailer's version, vdb_io.hpp).
    std::string vdb_a = BytesWithoutUtcTimes(small / "tsdf.vdb"),
                vdb_b = BytesWithoutUtcTimes(whole / "tsdf.vdb");
    ASSERT_EQ(vdb_a.size(), vdb_b.size());
    ASSERT_GT(vdb_a.size(), 64u);
    for (std::string* v : {&vdb_a, &vdb_b}) {
        v->replace(21, 36, 36, '-');
        v->replace(v->size() - 8, 4, 4, '-');
    }
    EXPECT_TRUE(vdb_a == vdb_b);
    for (const char* f : {"mesh.ply", "mesh_filled.ply", "mesh.glb", "mesh_utm.ply"}) {
        ASSERT_TRUE(fs::exists(whole / f)) << f;
        EXPECT_TRUE(BytesWithoutUtcTimes(small / f) == BytesWithoutUtcTimes(whole / f)) << f;
    }
}

}  // namespace
