// SPDX-License-Identifier: MIT
// Tiles for large areas (issue 38 item 2; docs/tiles.md): the CUBE grid and the TSDF computed
// tile by tile, each tile alone from the data around it, every node and voxel of a tile's core
// identical to a whole-survey run; products as tiles beside the whole ones:
//   P/tiles/dem/dem_I_J.tif   Cloud Optimized GeoTIFF of tile (I, J)'s core nodes (dem.tif's
//                             bands, CRS and metadata), and P/tiles/dem.vrt, a GDAL VRT of them
//   P/tiles/mesh/mesh_I_J.glb the iso-surface triangles whose centroid lies in the core of
//                             TSDF tile (I, J) (fusion::KeepTrianglesIn: the seam rule), and
//                             P/tiles/mesh/index.json: each tile's bounds, file and counts
// Lattices. A tile is square, tile_size_m nominal, in each product's own lattice so that a node
// or voxel belongs to exactly one tile's core:
//   grid: global nodes (hydro/cube.hpp; UTM metres) in blocks of n = max(1, round(T / res));
//         tile (I, J) holds nodes i in [I n, (I + 1) n), j alike;
//   TSDF: voxel columns (local ENU, voxel centres at integer multiples of the voxel size) in
//         blocks of m voxels, m = T / voxel rounded to a multiple of fusion::kRegionAlignVoxels
//         (the rasteriser's slabs); tile (I, J) holds x in [I m, (I + 1) m), y alike.
// So grid tile (I, J) and TSDF tile (I, J) are different squares (UTM against the survey's ENU).
// Overlap: a grid tile takes the soundings within overlap_m of its core (>= CUBE's reach,
// hydro::CubeTileReach); a TSDF tile integrates the voxels within overlap_m of its core
// (rounded up to kRegionAlignVoxels), so that its mesh near the seam comes from the same voxels
// as the whole mesh (>= the truncation).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "processor/fusion/tsdf.hpp"
#include "processor/hydro/cube.hpp"

namespace pitmap::proc::pipeline {

struct TilesConfig {
    bool enabled = false;        // grid and fuse by tiles, and the tiled products
    double tile_size_m = 100;    // nominal tile edge, m
    double overlap_m = 12;       // data taken around a tile's core, m (checks below)
    bool write_products = true;  // P/tiles/ (dem tiles + VRT, mesh tiles + index)

    std::vector<std::string> Validate() const;
};

// A tile's index in its lattice.
struct TileIndex {
    std::int64_t i = 0, j = 0;
    bool operator==(const TileIndex&) const = default;
};

// Least tile, in grid nodes or voxels.
inline constexpr int kMinTileNodes = 8;

// Every problem of `tiles` against the TSDF's and CUBE's settings, known at start: a tile
// smaller than the TSDF's alignment (kRegionAlignVoxels voxels) or than kMinTileNodes grid
// nodes (an explicit grid.resolution_m), an overlap below the truncation or below CUBE's reach.
std::vector<std::string> ValidateTiles(const TilesConfig& tiles,
                                       const fusion::TsdfConfig& tsdf,
                                       const hydro::CubeConfig& cube);
// The grid's problems once its resolution is known (grid.resolution_m 0: from the depth).
std::vector<std::string> ValidateGridTiles(const TilesConfig& tiles,
                                           double resolution_m,
                                           const hydro::CubeConfig& cube);

// Grid nodes per tile edge, and the tiles covering `survey` with their core nodes (the tile's
// block cut to the survey), row by row from the south-west.
std::int64_t NodesPerTile(const TilesConfig& tiles, double resolution_m);
struct GridTile {
    TileIndex index;
    hydro::CubeNodeRange core;
};
std::vector<GridTile> GridTiles(const hydro::CubeNodeRange& survey, std::int64_t nodes_per_tile);

// TSDF voxels per tile edge (a multiple of kRegionAlignVoxels) and overlap (the same), and the
// tiles whose core meets the voxel columns [x_min, x_max] x [y_min, y_max].
int VoxelsPerTile(const TilesConfig& tiles, double voxel_size_m);
int OverlapVoxels(const TilesConfig& tiles, double voxel_size_m);
struct VoxelTile {
    TileIndex index;
    fusion::VoxelColumns core;
    fusion::VoxelColumns region;  // core grown by the overlap
};
std::vector<VoxelTile> VoxelTiles(const fusion::VoxelColumns& extent,
                                  int voxels_per_tile,
                                  int overlap_voxels);

// floor(a / b), b > 0.
std::int64_t FloorDiv(std::int64_t a, std::int64_t b);

// "I_J" of file names (negative indices as "m3": dem_m3_12.tif).
std::string TileName(const TileIndex& t);

}  // namespace pitmap::proc::pipeline
