// SPDX-License-Identifier: MIT
// The live coverage grid: soundings binned into square UTM cells as they arrive, kept in
// tiles of kTileCells x kTileCells cells that carry the version of their last change (a stamp
// unique to the tile, increasing), so a client fetches only what changed since it last asked.
//
// Per cell: sounding count (density), mean elevation (ellipsoidal height, as the soundings),
// mean depth below the transducer, elevation standard deviation.
// Holidays: an empty cell inside the covered area. A cell counts as inside when covered cells
// lie within `holiday_search_cells` cells on both sides of it along its row, or along its
// column (a gap in a swath, or between two adjacent lines); the open edges of the survey are not
// holidays.
// Memory: 24 bytes per cell of every touched tile; soundings that would open a tile beyond
// `max_tiles` are counted (soundings_dropped), not gridded.
// Thread safety: none; LiveSession serialises access.
#pragma once

#include <cstdint>
#include <string>
#include <unordered_map>
#include <vector>

#include "processor/io/grid_io.hpp"

namespace pitmap::proc::live {

inline constexpr int kTileCells = 32;  // cells along a tile's side

struct CoverageGridConfig {
    double cell_size_m = 1.0;        // cell side, metres (UTM)
    int holiday_search_cells = 4;    // cells each side that must hold soundings, 1..16
    std::size_t max_tiles = 40'000;  // 40 000 tiles = 41 M cells, ~1 GB; the memory bound
    std::vector<std::string> Validate() const;
};

struct GridCell {
    std::uint32_t count = 0;
    float sum_depth_m = 0;
    double sum_elevation_m = 0;
    double sum_elevation2_m2 = 0;
};

struct GridTile {
    int tx = 0, ty = 0;           // tile index: cells [tx * kTileCells, (tx + 1) * kTileCells)
    std::uint64_t version = 0;    // stamp of the last change, unique among tiles
    std::uint64_t batch = 0;      // the caller's batch of the last change
    int filled = 0;               // cells with at least one sounding
    std::vector<GridCell> cells;  // kTileCells^2, row-major from the south (j * kTileCells + i)
};

struct CoverageStats {
    std::int64_t soundings = 0;          // gridded
    std::int64_t soundings_dropped = 0;  // beyond max_tiles, or not finite
    std::int64_t filled_cells = 0;
    std::int64_t holidays = 0;
    std::int64_t tiles = 0;
    double covered_area_m2 = 0;               // filled_cells * cell area
    double min_depth_m = 0, max_depth_m = 0;  // over the filled cells' means; 0 when empty
    // Cell index bounds of the filled cells (inclusive); empty when filled_cells == 0.
    std::int64_t min_ix = 0, min_iy = 0, max_ix = 0, max_iy = 0;
};

class CoverageGrid {
public:
    explicit CoverageGrid(const CoverageGridConfig& config);

    // Adds one sounding at UTM (easting, northing), with its ellipsoidal height and its depth
    // below the transducer. `batch` groups soundings (non-decreasing across calls): a tile
    // gets a new version once per batch that changes it.
    void Add(double easting_m,
             double northing_m,
             double elevation_m,
             double depth_m,
             std::uint64_t batch);
    // The newest tile version (0 = empty).
    std::uint64_t version() const { return stamp_; }

    const CoverageGridConfig& config() const { return config_; }
    // Cell index of a coordinate (floor(x / cell_size)).
    std::int64_t CellIndex(double coordinate_m) const;
    // The cell, or nullptr when its tile does not exist.
    const GridCell* Cell(std::int64_t ix, std::int64_t iy) const;
    bool IsHoliday(std::int64_t ix, std::int64_t iy) const;
    // Every holiday cell (ix, iy), at most `limit`; `total` receives how many there are.
    std::vector<std::pair<std::int64_t, std::int64_t>> Holidays(std::size_t limit,
                                                                std::int64_t* total) const;
    // With holidays = false, CoverageStats::holidays stays 0 (counting them visits every empty
    // cell of every tile).
    CoverageStats Stats(bool with_holidays = true) const;
    // Tiles changed after `since`, oldest change first.
    std::vector<const GridTile*> TilesSince(std::uint64_t since) const;
    std::size_t num_tiles() const { return tiles_.size(); }

    // The filled extent as a raster in the UTM zone given: layers depth (m, below the
    // transducer), elevation (m, ellipsoidal), elevation_stddev (m), density (soundings per
    // cell) and holiday (1 = holiday, 0 = not); NaN = empty. Error when empty or larger than
    // max_cells.
    Expected<io::GridRaster> ToRaster(int utm_zone,
                                      bool northern,
                                      std::size_t max_cells = 100'000'000) const;

private:
    static std::int64_t Key(std::int64_t tx, std::int64_t ty);
    bool Filled(std::int64_t ix, std::int64_t iy) const;

    CoverageGridConfig config_;
    std::unordered_map<std::int64_t, GridTile> tiles_;
    std::int64_t soundings_ = 0, dropped_ = 0, filled_ = 0;
    std::uint64_t stamp_ = 0;
};

}  // namespace pitmap::proc::live
