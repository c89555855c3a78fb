// SPDX-License-Identifier: MIT
// The live coverage grid: soundings binned into square UTM cells as they arrive, kept in
// tiles of kTileCells x kTileCells cells that carry the version of their last change (a stamp
// unique to the tile, increasing), so a client fetches only what changed since it last asked.
//
// Per cell: sounding count (density), mean elevation (ellipsoidal height, as the soundings),
// mean depth below the transducer, elevation standard deviation, and the TVU status against the
// configured IHO S-44 order (processor/hydro/s44.hpp): how many of the cell's soundings have a
// TVU (95 %, processor/hydro/tpu.hpp) over the order's limit sqrt(a^2 + (b d)^2) at their own
// depth d below the transducer, and the sum of their TVU (the cell's mean TVU). A cell meets the
// order when at least tvu_min_share of its soundings are within the limit (S-44's 95 %). A
// sounding without a finite TVU counts as over the limit.
// Holidays: an empty cell inside the covered area. A cell counts as inside when covered cells
// lie within `holiday_search_cells` cells on both sides of it along its row, or along its
// column (a gap in a swath, or between two adjacent lines); the open edges of the survey are not
// holidays.
// Memory: 32 bytes per cell (sizeof(GridCell), checked below), so 32 KiB per touched tile plus
// about 100 bytes of tile and hash-map overhead: max_tiles = 40 000 bounds the grid at 1.3 GB.
// Soundings that would open a tile beyond `max_tiles` are counted (soundings_dropped), not
// gridded.
// Thread safety: none; LiveSession serialises access.
#pragma once

#include <cstdint>
#include <string>
#include <unordered_map>
#include <vector>

#include "processor/hydro/s44.hpp"
#include "processor/io/grid_io.hpp"

namespace pitmap::proc::live {

inline constexpr int kTileCells = 32;  // cells along a tile's side

struct CoverageGridConfig {
    double cell_size_m = 1.0;        // cell side, metres (UTM)
    int holiday_search_cells = 4;    // cells each side that must hold soundings, 1..16
    std::size_t max_tiles = 40'000;  // 40 000 tiles = 41 M cells, 1.3 GB; the memory bound
    std::string s44_order = "1a";    // TVU status: exclusive | special | 1a | 1b | 2
    double tvu_min_share = 0.95;     // a cell meets the order with this share within, (0, 1]
    std::vector<std::string> Validate() const;
};

struct GridCell {
    std::uint32_t count = 0;
    float sum_depth_m = 0;
    double sum_elevation_m = 0;
    double sum_elevation2_m2 = 0;
    std::uint32_t tvu_over = 0;  // soundings with TVU over the order's limit at their depth
    float sum_tvu_m = 0;         // sum of the soundings' TVU (95 %), m
};
static_assert(sizeof(GridCell) == 32, "the header's memory figures assume 32 bytes per cell");

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
    std::int64_t cells_tvu_failing = 0;       // filled cells that do not meet the order's TVU
    std::int64_t soundings_tvu_over = 0;      // gridded soundings over the order's TVU limit
    double covered_area_m2 = 0;               // filled_cells * cell area
    double min_depth_m = 0, max_depth_m = 0;  // over the filled cells' means; 0 when empty
    // Cell index bounds of the filled cells (inclusive); empty when filled_cells == 0.
    std::int64_t min_ix = 0, min_iy = 0, max_ix = 0, max_iy = 0;
};

class CoverageGrid {
public:
    explicit CoverageGrid(const CoverageGridConfig& config);

    // Adds one sounding at UTM (easting, northing), with its ellipsoidal height, its depth
    // below the transducer and its TVU (95 %, m). `batch` groups soundings (non-decreasing
    // across calls): a tile gets a new version once per batch that changes it. True when the
    // sounding is the first of its cell.
    bool Add(double easting_m,
             double northing_m,
             double elevation_m,
             double depth_m,
             double tvu_95_m,
             std::uint64_t batch);
    // The newest tile version (0 = empty).
    std::uint64_t version() const { return stamp_; }

    const CoverageGridConfig& config() const { return config_; }
    // Cell index of a coordinate (floor(x / cell_size)).
    std::int64_t CellIndex(double coordinate_m) const;
    // The cell, or nullptr when its tile does not exist.
    const GridCell* Cell(std::int64_t ix, std::int64_t iy) const;
    // The order the TVU status is held to, and whether a filled cell meets it.
    hydro::S44Order order() const { return order_; }
    bool MeetsTvu(const GridCell& c) const;
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
    // cell), holiday (1 = holiday, 0 = not), tvu_95 (the cell's mean TVU, m) and
    // tvu_meets_order (1 = meets the order, 0 = fails); NaN = empty. Error when empty or larger
    // than max_cells.
    Expected<io::GridRaster> ToRaster(int utm_zone,
                                      bool northern,
                                      std::size_t max_cells = 100'000'000) const;

private:
    static std::int64_t Key(std::int64_t tx, std::int64_t ty);
    bool Filled(std::int64_t ix, std::int64_t iy) const;

    CoverageGridConfig config_;
    hydro::S44Order order_ = hydro::S44Order::kOrder1a;
    hydro::S44Limits limits_;
    std::int64_t tvu_failing_ = 0, tvu_over_ = 0;
    std::unordered_map<std::int64_t, GridTile> tiles_;
    std::int64_t soundings_ = 0, dropped_ = 0, filled_ = 0;
    std::uint64_t stamp_ = 0;
};

}  // namespace pitmap::proc::live
