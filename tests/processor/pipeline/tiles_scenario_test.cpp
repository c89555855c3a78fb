// SPDX-License-Identifier: MIT
// Scenario test of tiles (issue 38 item 2; processor/pipeline/tiles.hpp, docs/tiles.md): the
// first 120 s of bejanca run whole and by tiles (40 m tiles, 12 m overlap). The tiled run's
// DEM equals the whole run's node for node (every band, max difference 0), its TSDF voxel for
// voxel (distance and weight bit for bit), the DEM tiles' VRT reads back as the DEM, and the mesh
// tiles hold the whole mesh's triangles. Each TSDF tile run alone (`pitmap fuse --tile I,J`)
// and merged (`--merge-tiles`) gives the whole TSDF again; each DEM tile alone (`pitmap grid
// --tile I,J`) equals the whole DEM over its area node for node. A tile size too small for the
// voxel size and an overlap below the truncation stop the run at start, naming both.
// PITMAP_TILES_DURATION_S sets another duration (docs/tiles.md measures the whole survey so).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <tuple>
#include <vector>

#include "processor/fusion/vdb_io.hpp"
#include "processor/io/grid_io.hpp"
#include "tests/support/process.hpp"
#include "tests/support/scenario.hpp"

namespace {

namespace fs = std::filesystem;
using pitmap::test::kBin;
using pitmap::test::Quote;
using pitmap::test::ReadJson;
using pitmap::test::RunCommand;

std::uint32_t Bits(float v) {
    std::uint32_t b;
    std::memcpy(&b, &v, sizeof b);
    return b;
}

using Voxel = std::tuple<int, int, int, std::uint32_t, std::uint32_t>;
std::vector<Voxel> Voxels(const fs::path& vdb) {
    auto v = pitmap::proc::fusion::ReadVdb(vdb.string());
    EXPECT_TRUE(v) << vdb;
    std::vector<Voxel> out;
    if (!v) return out;
    v->ForEachVoxel([&](const Eigen::Vector3i& c, float d, float w) {
        out.emplace_back(c.x(), c.y(), c.z(), Bits(d), Bits(w));
    });
    std::sort(out.begin(), out.end());
    return out;
}

// Largest |a - b| over the nodes of two rasters of one geometry (NaN against a value: inf).
double MaxDifference(const std::vector<float>& a, const std::vector<float>& b) {
    double worst = 0;
    for (std::size_t k = 0; k < a.size(); ++k) {
        if (std::isnan(a[k]) != std::isnan(b[k])) return INFINITY;
        if (!std::isnan(a[k])) worst = std::max(worst, std::abs(double{a[k]} - double{b[k]}));
    }
    return worst;
}

TEST(TilesScenario, TiledBejancaEqualsTheWholeRunAtTheSeams) {
    const char* env = std::getenv("PITMAP_TILES_DURATION_S");
    const std::string duration = env != nullptr ? env : "120";
    const fs::path dir = pitmap::test::FreshDir("pitmap_tiles_scenario");
    std::string out;
    ASSERT_EQ(RunCommand(kBin + "/pitmap-sim synth --scenario bejanca --duration " + duration +
                             " --out " + Quote(dir / "sim"),
                         &out),
              0)
        << out;
    std::ofstream(dir / "tiled.yaml")
        << "tiles:\n  enabled: true\n  tile_size_m: 40\n  overlap_m: 12\n";
    const fs::path whole = dir / "whole", tiled = dir / "tiled";
    ASSERT_EQ(RunCommand(kBin + "/pitmap run " + Quote(dir / "sim/log") + " --no-report --out " +
                             Quote(whole),
                         &out),
              0)
        << out;
    ASSERT_EQ(RunCommand(kBin + "/pitmap run " + Quote(dir / "sim/log") + " --no-report --out " +
                             Quote(tiled) + " --config " + Quote(dir / "tiled.yaml"),
                         &out),
              0)
        << out;

    // The DEM, every band.
    auto a = pitmap::proc::io::ReadGrid((whole / "dem.tif").string());
    auto b = pitmap::proc::io::ReadGrid((tiled / "dem.tif").string());
    ASSERT_TRUE(a && b);
    ASSERT_EQ(a->grid.nx, b->grid.nx);
    ASSERT_EQ(a->grid.ny, b->grid.ny);
    EXPECT_EQ(a->grid.x0, b->grid.x0);
    EXPECT_EQ(a->grid.y0, b->grid.y0);
    ASSERT_EQ(a->grid.layers.size(), b->grid.layers.size());
    for (std::size_t l = 0; l < a->grid.layers.size(); ++l) {
        const double d = MaxDifference(a->grid.layers[l].values, b->grid.layers[l].values);
        RecordProperty("dem_max_difference_" + a->grid.layers[l].name, std::to_string(d));
        EXPECT_EQ(d, 0.0) << a->grid.layers[l].name;
    }
    const auto grid = ReadJson(tiled / "summary.json")["stages"]["grid"];
    ASSERT_TRUE(grid.contains("tiles")) << grid.dump();
    EXPECT_GE(grid["tiles"]["dem_tiles"].size(), 4u);  // the seams are crossed

    // The VRT of the DEM tiles reads back as the DEM where it has tiles.
    auto vrt = pitmap::proc::io::ReadGrid((tiled / "tiles/dem.vrt").string());
    ASSERT_TRUE(vrt) << vrt.error().message;
    const auto& v = vrt->grid;
    const double res = a->grid.resolution_m;
    EXPECT_NEAR(v.resolution_m, res, 1e-9 * res);  // GDAL divides the extent by the size
    const long di = std::lround((v.x0 - a->grid.x0) / res);
    const long dj = std::lround((v.y0 - a->grid.y0) / res);
    std::int64_t compared = 0, differing = 0;
    for (int j = 0; j < v.ny; ++j) {
        for (int i = 0; i < v.nx; ++i) {
            const long ai = i + di, aj = j + dj;
            if (ai < 0 || aj < 0 || ai >= a->grid.nx || aj >= a->grid.ny) continue;
            const float x = v.layers[0].values[static_cast<std::size_t>(j) * v.nx + i];
            const float y =
                a->grid.layers[0].values[static_cast<std::size_t>(aj) * a->grid.nx + ai];
            if (std::isnan(x) && std::isnan(y)) continue;
            ++compared;
            if (Bits(x) != Bits(y)) ++differing;
        }
    }
    EXPECT_GT(compared, 10000);
    EXPECT_EQ(differing, 0);

    // The TSDF, voxel for voxel.
    const std::vector<Voxel> va = Voxels(whole / "tsdf.vdb");
    const std::vector<Voxel> vb = Voxels(tiled / "tsdf.vdb");
    RecordProperty("tsdf_voxels", std::to_string(va.size()));
    ASSERT_GT(va.size(), 100000u);
    EXPECT_EQ(va.size(), vb.size());
    EXPECT_TRUE(va == vb);

    // The mesh tiles: the whole raw mesh's triangles, split by the seam rule.
    const auto fuse = ReadJson(tiled / "summary.json")["stages"]["fuse"];
    const auto mesh = ReadJson(whole / "summary.json")["stages"]["mesh"];
    ASSERT_TRUE(fuse.contains("tiles")) << fuse.dump();
    EXPECT_EQ(fuse["tiles"]["mesh_tile_triangles"], mesh["triangles"]);
    const auto index = ReadJson(tiled / "tiles/mesh/index.json");
    ASSERT_GE(index["tiles"].size(), 4u);
    std::int64_t triangles = 0;
    for (const auto& t : index["tiles"]) {
        EXPECT_TRUE(fs::exists(tiled / "tiles/mesh" / t["file"].get<std::string>()));
        triangles += t["triangles"].get<std::int64_t>();
    }
    EXPECT_EQ(triangles, mesh["triangles"].get<std::int64_t>());

    // Each tile alone (`pitmap fuse --tile I,J`, a campaign's per-tile job) on a copy of the
    // whole run's folder, then the merge: `pitmap fuse` of the whole survey on that folder
    // again, voxel for voxel (a fuse command loads the saved survey, whose view can differ from
    // the run's by the grid's surface filter: the reference is the same command whole).
    const fs::path jobs = dir / "jobs", again = dir / "again";
    fs::copy(whole, jobs, fs::copy_options::recursive);
    fs::copy(whole, again, fs::copy_options::recursive);
    ASSERT_EQ(RunCommand(kBin + "/pitmap fuse --out " + Quote(again), &out), 0) << out;
    const auto& ij = fuse["tiles"]["tiles_with_voxels_ij"];
    ASSERT_GE(ij.size(), 4u);
    for (const auto& t : ij) {
        const std::string tile =
            std::to_string(t[0].get<int>()) + "," + std::to_string(t[1].get<int>());
        ASSERT_EQ(RunCommand(kBin + "/pitmap fuse --out " + Quote(jobs) + " --config " +
                                 Quote(dir / "tiled.yaml") + " --tile=" + tile,
                             &out),
                  0)
            << tile << ": " << out;
    }
    ASSERT_EQ(RunCommand(kBin + "/pitmap fuse --out " + Quote(jobs) + " --config " +
                             Quote(dir / "tiled.yaml") + " --merge-tiles",
                         &out),
              0)
        << out;
    const std::vector<Voxel> vj = Voxels(jobs / "tsdf.vdb");
    EXPECT_GT(vj.size(), 100000u);
    EXPECT_TRUE(vj == Voxels(again / "tsdf.vdb"));
    const auto merged = ReadJson(jobs / "tiles/mesh/index.json");
    std::int64_t merged_triangles = 0;
    for (const auto& t : merged["tiles"]) merged_triangles += t["triangles"].get<std::int64_t>();
    auto again_volume = pitmap::proc::fusion::ReadVdb((again / "tsdf.vdb").string());
    ASSERT_TRUE(again_volume);
    EXPECT_EQ(merged_triangles,
              static_cast<std::int64_t>(again_volume->ExtractIsoSurface().mesh.triangles.size()));
    // A tile the survey does not have is refused, naming it.
    EXPECT_NE(RunCommand(kBin + "/pitmap fuse --out " + Quote(jobs) + " --config " +
                             Quote(dir / "tiled.yaml") + " --tile=900,900 2>&1",
                         &out),
              0);
    EXPECT_NE(out.find("tile 900_900 is not one of the survey's"), std::string::npos) << out;
    // A tile that is not two integers, and the two steps in one command, are refused.
    EXPECT_NE(RunCommand(kBin + "/pitmap fuse --out " + Quote(jobs) + " --config " +
                             Quote(dir / "tiled.yaml") + " --tile=1,x 2>&1",
                         &out),
              0);
    EXPECT_NE(out.find("expected I,J"), std::string::npos) << out;
    EXPECT_NE(RunCommand(kBin + "/pitmap fuse --out " + Quote(jobs) + " --config " +
                             Quote(dir / "tiled.yaml") + " --tile=0,0 --merge-tiles 2>&1",
                         &out),
              0);
    EXPECT_NE(out.find("give one of them"), std::string::npos) << out;

    // Each DEM tile alone (`pitmap grid --tile I,J`, a campaign's per-tile job) on the copy of
    // the whole run's folder (which has no tiles/ of its own): node for node the dem.tif of
    // `pitmap grid` of the whole survey on that folder, in every band. (As for the fuse, the
    // reference is the same command whole: a command loads the saved survey, and on bejanca
    // the run's own dem.tif differs from it at 9 nodes by 1 ulp of the uncertainty.) The first
    // two run side by side (the tile commands share P's lock).
    ASSERT_EQ(RunCommand(kBin + "/pitmap grid --out " + Quote(again), &out), 0) << out;
    auto ref = pitmap::proc::io::ReadGrid((again / "dem.tif").string());
    ASSERT_TRUE(ref);
    const auto& dem_tiles = grid["tiles"]["dem_tiles"];
    ASSERT_GE(dem_tiles.size(), 4u);
    const auto grid_tile = [&](const nlohmann::json& t) {
        return kBin + "/pitmap grid --out " + Quote(jobs) + " --config " +
               Quote(dir / "tiled.yaml") + " --tile=" + std::to_string(t["i"].get<int>()) + "," +
               std::to_string(t["j"].get<int>());
    };
    ASSERT_EQ(RunCommand("(" + grid_tile(dem_tiles[0]) + ") & a=$!; " + grid_tile(dem_tiles[1]) +
                             "; b=$?; wait $a && [ $b -eq 0 ]",
                         &out),
              0)
        << out;
    std::int64_t tile_nodes = 0, tile_differing = 0, tile_outside = 0;
    for (std::size_t k = 0; k < dem_tiles.size(); ++k) {
        const auto& t = dem_tiles[k];
        if (k >= 2) {
            ASSERT_EQ(RunCommand(grid_tile(t), &out), 0) << t.dump() << ": " << out;
        }
        const std::string name =
            "dem_" + std::to_string(t["i"].get<int>()) + "_" + std::to_string(t["j"].get<int>());
        auto alone = pitmap::proc::io::ReadGrid((jobs / "tiles/dem" / (name + ".tif")).string());
        ASSERT_TRUE(alone) << name;
        const auto& g = alone->grid;
        ASSERT_EQ(g.layers.size(), ref->grid.layers.size());
        const long ti = std::lround((g.x0 - ref->grid.x0) / res);
        const long tj = std::lround((g.y0 - ref->grid.y0) / res);
        for (int j = 0; j < g.ny; ++j) {
            for (int i = 0; i < g.nx; ++i) {
                const std::size_t at = static_cast<std::size_t>(j) * g.nx + i;
                const long ai = i + ti, aj = j + tj;
                if (ai < 0 || aj < 0 || ai >= ref->grid.nx || aj >= ref->grid.ny) {
                    if (!std::isnan(g.layers[0].values[at])) ++tile_outside;
                    continue;
                }
                const std::size_t wa = static_cast<std::size_t>(aj) * ref->grid.nx + ai;
                ++tile_nodes;
                for (std::size_t l = 0; l < g.layers.size(); ++l) {
                    const float x = g.layers[l].values[at], y = ref->grid.layers[l].values[wa];
                    if (std::isnan(x) && std::isnan(y)) continue;
                    if (Bits(x) != Bits(y)) {
                        ++tile_differing;
                        break;
                    }
                }
            }
        }
        EXPECT_TRUE(fs::exists(jobs / "tiles/dem" / (name + ".json"))) << name;
    }
    RecordProperty("dem_tiles_alone_nodes", std::to_string(tile_nodes));
    EXPECT_GT(tile_nodes, 10000);
    EXPECT_EQ(tile_differing, 0);
    EXPECT_EQ(tile_outside, 0);
    EXPECT_NE(RunCommand(kBin + "/pitmap grid --out " + Quote(jobs) + " --config " +
                             Quote(dir / "tiled.yaml") + " --tile=900,900 2>&1",
                         &out),
              0);
    EXPECT_NE(out.find("grid --tile 900_900: the survey has no such tile"), std::string::npos)
        << out;
}

TEST(TilesScenario, TilesTooSmallForTheVoxelsStopTheRunAtStart) {
    const fs::path dir = pitmap::test::FreshDir("pitmap_tiles_bad_config");
    std::ofstream(dir / "bad.yaml")
        << "fuse:\n  voxel_size_m: 0.1\n  truncation_m: 1.5\n"
           "tiles:\n  enabled: true\n  tile_size_m: 5\n  overlap_m: 0.5\n";
    std::string out;
    // No survey is needed: the config is checked before any input is read.
    EXPECT_NE(RunCommand(kBin + "/pitmap run " + Quote(dir / "missing") + " --out " +
                             Quote(dir / "P") + " --config " + Quote(dir / "bad.yaml") + " 2>&1",
                         &out),
              0);
    EXPECT_NE(out.find("tiles.tile_size_m (5 m) is too small for fuse.voxel_size_m (0.1 m)"),
              std::string::npos)
        << out;
    EXPECT_NE(out.find("tiles.overlap_m (0.5 m) is below fuse.truncation_m (1.5 m)"),
              std::string::npos)
        << out;
    EXPECT_FALSE(fs::exists(dir / "P" / "summary.json"));
}

}  // namespace
