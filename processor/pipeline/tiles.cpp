// SPDX-License-Identifier: MIT
#include "processor/pipeline/tiles.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace pitmap::proc::pipeline {

namespace {

std::string Metres(double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.3g m", v);
    return buf;
}

}  // namespace

std::vector<std::string> TilesConfig::Validate() const {
    std::vector<std::string> p;
    if (!(std::isfinite(tile_size_m) && tile_size_m > 0)) {
        p.push_back("tiles.tile_size_m must be > 0");
    } else if (tile_size_m > 100'000) {
        p.push_back("tiles.tile_size_m must be at most 100 km");
    }
    if (!(std::isfinite(overlap_m) && overlap_m >= 0)) p.push_back("tiles.overlap_m must be >= 0");
    return p;
}

std::vector<std::string> ValidateTiles(const TilesConfig& tiles,
                                       const fusion::TsdfConfig& tsdf,
                                       const hydro::CubeConfig& cube) {
    std::vector<std::string> p;
    if (!tiles.enabled) return p;
    if (!tiles.Validate().empty() || !(tsdf.voxel_size_m > 0)) return p;  // listed elsewhere
    const double least_tsdf = fusion::kRegionAlignVoxels * tsdf.voxel_size_m;
    if (tiles.tile_size_m < least_tsdf) {
        p.push_back("tiles.tile_size_m (" + Metres(tiles.tile_size_m) +
                    ") is too small for fuse.voxel_size_m (" + Metres(tsdf.voxel_size_m) +
                    "): a TSDF tile is a multiple of " +
                    std::to_string(fusion::kRegionAlignVoxels) + " voxels, at least " +
                    Metres(least_tsdf));
    }
    if (tiles.overlap_m < tsdf.truncation_m) {
        p.push_back("tiles.overlap_m (" + Metres(tiles.overlap_m) +
                    ") is below fuse.truncation_m (" + Metres(tsdf.truncation_m) +
                    "): a tile's mesh at the seam needs the voxels of the band beyond it");
    }
    if (cube.resolution_m > 0) {
        for (std::string& s : ValidateGridTiles(tiles, cube.resolution_m, cube)) {
            p.push_back(std::move(s));
        }
    }
    return p;
}

std::vector<std::string> ValidateGridTiles(const TilesConfig& tiles,
                                           double resolution_m,
                                           const hydro::CubeConfig& cube) {
    std::vector<std::string> p;
    if (!tiles.enabled) return p;
    const double least = kMinTileNodes * resolution_m;
    if (tiles.tile_size_m < least) {
        p.push_back("tiles.tile_size_m (" + Metres(tiles.tile_size_m) +
                    ") is too small for the grid resolution (" + Metres(resolution_m) +
                    "): at least " + std::to_string(kMinTileNodes) + " nodes, " + Metres(least));
    }
    const double reach = hydro::CubeTileReach(resolution_m, cube);
    if (tiles.overlap_m < reach) {
        p.push_back("tiles.overlap_m (" + Metres(tiles.overlap_m) +
                    ") is below CUBE's reach at the grid resolution " + Metres(resolution_m) +
                    " (" + Metres(reach) +
                    ": the capture distance and two predicted-surface cells): the nodes at a "
                    "tile's edge would miss soundings");
    }
    return p;
}

std::int64_t FloorDiv(std::int64_t a, std::int64_t b) {
    return a >= 0 ? a / b : -((-a + b - 1) / b);
}

std::int64_t NodesPerTile(const TilesConfig& tiles, double resolution_m) {
    return std::max<std::int64_t>(1, std::llround(tiles.tile_size_m / resolution_m));
}

std::vector<GridTile> GridTiles(const hydro::CubeNodeRange& survey, std::int64_t n) {
    std::vector<GridTile> out;
    if (survey.i1 <= survey.i0 || survey.j1 <= survey.j0) return out;
    for (std::int64_t tj = FloorDiv(survey.j0, n); tj * n < survey.j1; ++tj) {
        for (std::int64_t ti = FloorDiv(survey.i0, n); ti * n < survey.i1; ++ti) {
            out.push_back({{ti, tj},
                           {std::max(survey.i0, ti * n),
                            std::max(survey.j0, tj * n),
                            std::min(survey.i1, (ti + 1) * n),
                            std::min(survey.j1, (tj + 1) * n)}});
        }
    }
    return out;
}

int VoxelsPerTile(const TilesConfig& tiles, double voxel_size_m) {
    const double blocks = std::round(tiles.tile_size_m / voxel_size_m / fusion::kRegionAlignVoxels);
    return static_cast<int>(std::max(1.0, blocks)) * fusion::kRegionAlignVoxels;
}

int OverlapVoxels(const TilesConfig& tiles, double voxel_size_m) {
    const double blocks = std::ceil(tiles.overlap_m / voxel_size_m / fusion::kRegionAlignVoxels);
    return static_cast<int>(blocks) * fusion::kRegionAlignVoxels;
}

std::vector<VoxelTile> VoxelTiles(const fusion::VoxelColumns& extent, int m, int overlap) {
    std::vector<VoxelTile> out;
    if (extent.x_max < extent.x_min || extent.y_max < extent.y_min) return out;
    for (std::int64_t tj = FloorDiv(extent.y_min, m); tj <= FloorDiv(extent.y_max, m); ++tj) {
        for (std::int64_t ti = FloorDiv(extent.x_min, m); ti <= FloorDiv(extent.x_max, m); ++ti) {
            VoxelTile t;
            t.index = {ti, tj};
            t.core = {static_cast<std::int32_t>(ti * m),
                      static_cast<std::int32_t>(ti * m + m - 1),
                      static_cast<std::int32_t>(tj * m),
                      static_cast<std::int32_t>(tj * m + m - 1)};
            t.region = {t.core.x_min - overlap,
                        t.core.x_max + overlap,
                        t.core.y_min - overlap,
                        t.core.y_max + overlap};
            out.push_back(t);
        }
    }
    return out;
}

std::string TileName(const TileIndex& t) {
    const auto part = [](std::int64_t v) {
        return v < 0 ? "m" + std::to_string(-v) : std::to_string(v);
    };
    return part(t.i) + "_" + part(t.j);
}

}  // namespace pitmap::proc::pipeline
