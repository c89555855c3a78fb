// SPDX-License-Identifier: MIT
// The tile scheme (processor/pipeline/tiles.hpp): every node and voxel in exactly one tile's
// core, tiles aligned to the TSDF's slabs, names of negative indices; validation lists every
// problem with the values (a tile too small for the voxels or the grid, an overlap below the
// truncation or CUBE's reach), and the config file's `tiles:` section.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>

#include "processor/pipeline/pipeline.hpp"
#include "processor/pipeline/tiles.hpp"

namespace pitmap::proc::pipeline {
namespace {

bool Mentions(const std::vector<std::string>& problems, const std::string& text) {
    for (const std::string& p : problems) {
        if (p.find(text) != std::string::npos) return true;
    }
    return false;
}

TEST(Tiles, EveryNodeIsInExactlyOneCore) {
    const hydro::CubeNodeRange survey{-37, 1000003, 151, 1000090};
    const std::vector<GridTile> tiles = GridTiles(survey, 40);
    std::map<std::pair<std::int64_t, std::int64_t>, int> owner;
    for (const GridTile& t : tiles) {
        EXPECT_EQ(FloorDiv(t.core.i0, 40), t.index.i);
        EXPECT_EQ(FloorDiv(t.core.i1 - 1, 40), t.index.i);
        for (std::int64_t j = t.core.j0; j < t.core.j1; ++j) {
            for (std::int64_t i = t.core.i0; i < t.core.i1; ++i) ++owner[{i, j}];
        }
    }
    EXPECT_EQ(owner.size(), static_cast<std::size_t>(survey.nx() * survey.ny()));
    for (const auto& [node, n] : owner) ASSERT_EQ(n, 1);
    EXPECT_EQ(tiles.size(), 5u * 3u);  // i: blocks -1..3 (-40..159), j: 25000..25002
}

TEST(Tiles, VoxelTilesAreSlabAlignedAndCoverTheExtent) {
    TilesConfig c;
    c.tile_size_m = 30;
    c.overlap_m = 2;
    EXPECT_EQ(VoxelsPerTile(c, 0.1), 320);  // 300 voxels rounded to 5 x 64
    EXPECT_EQ(OverlapVoxels(c, 0.1), 64);   // 20 voxels rounded up
    c.tile_size_m = 1;
    EXPECT_EQ(VoxelsPerTile(c, 0.1), 64);
    const fusion::VoxelColumns extent{-700, 100, 5, 400};
    const auto tiles = VoxelTiles(extent, 320, 64);
    std::int64_t covered = 0;
    for (const VoxelTile& t : tiles) {
        EXPECT_TRUE(t.core.Aligned());
        EXPECT_TRUE(t.region.Aligned());
        EXPECT_EQ(t.region.x_min, t.core.x_min - 64);
        const std::int64_t w =
            std::min(t.core.x_max, extent.x_max) - std::max(t.core.x_min, extent.x_min) + 1;
        const std::int64_t h =
            std::min(t.core.y_max, extent.y_max) - std::max(t.core.y_min, extent.y_min) + 1;
        covered += w * h;
    }
    EXPECT_EQ(covered, (100 + 700 + 1) * (400 - 5 + 1));
    EXPECT_EQ(TileName({-3, 12}), "m3_12");
}

TEST(Tiles, ValidationNamesEveryProblemWithItsValues) {
    TilesConfig t;
    t.enabled = true;
    t.tile_size_m = 5;
    t.overlap_m = 0.5;
    fusion::TsdfConfig tsdf;
    tsdf.voxel_size_m = 0.1;
    tsdf.truncation_m = 1.5;
    hydro::CubeConfig cube;
    cube.resolution_m = 1.0;
    const auto p = ValidateTiles(t, tsdf, cube);
    EXPECT_TRUE(Mentions(p, "tiles.tile_size_m (5 m) is too small for fuse.voxel_size_m (0.1 m)"));
    EXPECT_TRUE(Mentions(p, "at least 6.4 m"));
    EXPECT_TRUE(Mentions(p, "tiles.overlap_m (0.5 m) is below fuse.truncation_m (1.5 m)"));
    EXPECT_TRUE(Mentions(p, "too small for the grid resolution (1 m): at least 8 nodes, 8 m"));
    EXPECT_TRUE(Mentions(p, "below CUBE's reach at the grid resolution 1 m (10.5 m"));
    EXPECT_EQ(p.size(), 4u);
    // Off: nothing to check; a sound setting: nothing to say.
    t.enabled = false;
    EXPECT_TRUE(ValidateTiles(t, tsdf, cube).empty());
    t = TilesConfig{};
    t.enabled = true;
    EXPECT_TRUE(ValidateTiles(t, tsdf, cube).empty());
    // The grid's resolution from the depth is checked when the grid stage knows it.
    EXPECT_FALSE(ValidateGridTiles(t, 5.0, cube).empty());
    EXPECT_TRUE(ValidateGridTiles(t, 0.5, cube).empty());
    t.tile_size_m = -1;
    t.overlap_m = std::numeric_limits<double>::quiet_NaN();
    EXPECT_EQ(t.Validate().size(), 2u);
}

TEST(Tiles, TheConfigSectionIsReadAndChecked) {
    const auto path = std::filesystem::temp_directory_path() / "pitmap_tiles_test.yaml";
    std::ofstream(path) << "tiles:\n  enabled: true\n  tile_size_m: 3\n  overlap_m: 0.1\n";
    // LoadConfig validates: every problem, each with its value.
    auto bad = LoadConfig(path.string());
    ASSERT_FALSE(bad);
    EXPECT_NE(bad.error().message.find("tiles.tile_size_m (3 m)"), std::string::npos);
    EXPECT_NE(bad.error().message.find("tiles.overlap_m (0.1 m)"), std::string::npos);
    std::ofstream(path) << "tiles:\n  enabled: true\n  tile_size_m: 64\n  overlap_m: 13\n";
    auto c = LoadConfig(path.string());
    ASSERT_TRUE(c) << c.error().message;
    EXPECT_TRUE(c->tiles.enabled);
    EXPECT_EQ(c->tiles.tile_size_m, 64);
    EXPECT_EQ(c->tiles.overlap_m, 13);
    EXPECT_NE(DefaultsYaml().find("\ntiles:\n  enabled: false"), std::string::npos);
    std::filesystem::remove(path);
}

}  // namespace
}  // namespace pitmap::proc::pipeline
