// SPDX-License-Identifier: MIT
#include "processor/live/coverage_grid.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace pitmap::proc::live {

namespace {

// Floor division for negative indices too.
std::int64_t FloorDiv(std::int64_t a, std::int64_t b) {
    std::int64_t q = a / b;
    if ((a % b != 0) && ((a < 0) != (b < 0))) --q;
    return q;
}

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

}  // namespace

std::vector<std::string> CoverageGridConfig::Validate() const {
    std::vector<std::string> p;
    if (!(cell_size_m >= 0.05 && cell_size_m <= 1000))
        p.push_back("live.cell_size_m must lie in [0.05, 1000]");
    if (holiday_search_cells < 1 || holiday_search_cells > kTileCells / 2)
        p.push_back("live.holiday_search_cells must lie in [1, 16]");
    if (max_tiles < 1) p.push_back("live.max_tiles must be at least 1");
    hydro::S44Order o;
    if (!hydro::S44OrderFromString(s44_order, &o)) {
        p.push_back("live.s44_order must be one of exclusive, special, 1a, 1b, 2 (not \"" +
                    s44_order + "\")");
    }
    if (!(tvu_min_share > 0 && tvu_min_share <= 1))
        p.push_back("live.tvu_min_share must lie in (0, 1]");
    return p;
}

CoverageGrid::CoverageGrid(const CoverageGridConfig& config) : config_(config) {
    // Validate() names a bad order; a grid built without it holds cells to 1a.
    hydro::S44OrderFromString(config_.s44_order, &order_);
    limits_ = hydro::LimitsOf(order_);
}

bool CoverageGrid::MeetsTvu(const GridCell& c) const {
    // over <= (1 - share) count, with a little slack for share = 0.95 exactly and count = 20.
    return c.count > 0 && static_cast<double>(c.tvu_over) <=
                              (1.0 - config_.tvu_min_share) * static_cast<double>(c.count) + 1e-9;
}

std::int64_t CoverageGrid::Key(std::int64_t tx, std::int64_t ty) {
    return static_cast<std::int64_t>((static_cast<std::uint64_t>(tx) << 32) ^
                                     (static_cast<std::uint64_t>(ty) & 0xffffffffULL));
}

std::int64_t CoverageGrid::CellIndex(double coordinate_m) const {
    return static_cast<std::int64_t>(std::floor(coordinate_m / config_.cell_size_m));
}

bool CoverageGrid::Add(double easting_m,
                       double northing_m,
                       double elevation_m,
                       double depth_m,
                       double tvu_95_m,
                       std::uint64_t batch) {
    // Tile indices must fit 32 bits (Key): |x / cell| < 2^31 * 32 is far beyond any UTM value.
    constexpr double kLimit = 1e9;
    if (!std::isfinite(easting_m) || !std::isfinite(northing_m) || !std::isfinite(elevation_m) ||
        !std::isfinite(depth_m) || std::abs(easting_m / config_.cell_size_m) > kLimit ||
        std::abs(northing_m / config_.cell_size_m) > kLimit) {
        ++dropped_;
        return false;
    }
    const std::int64_t ix = CellIndex(easting_m), iy = CellIndex(northing_m);
    const std::int64_t tx = FloorDiv(ix, kTileCells), ty = FloorDiv(iy, kTileCells);
    const std::int64_t key = Key(tx, ty);
    auto it = tiles_.find(key);
    if (it == tiles_.end()) {
        if (tiles_.size() >= config_.max_tiles) {
            ++dropped_;
            return false;
        }
        GridTile t;
        t.tx = static_cast<int>(tx);
        t.ty = static_cast<int>(ty);
        t.cells.resize(static_cast<std::size_t>(kTileCells) * kTileCells);
        it = tiles_.emplace(key, std::move(t)).first;
    }
    GridTile& tile = it->second;
    const auto i = static_cast<std::size_t>(ix - tx * kTileCells);
    const auto j = static_cast<std::size_t>(iy - ty * kTileCells);
    GridCell& c = tile.cells[j * kTileCells + i];
    const bool first = c.count == 0;
    if (first) {
        ++tile.filled;
        ++filled_;
    }
    const bool met = first || MeetsTvu(c);
    if (c.count < std::numeric_limits<std::uint32_t>::max()) {
        ++c.count;
        // The order's TVU limit at the sounding's own depth (S-44 Table 1).
        const bool within = std::isfinite(tvu_95_m) && tvu_95_m <= limits_.Tvu(std::abs(depth_m));
        if (!within) {
            ++c.tvu_over;
            ++tvu_over_;
        }
        if (std::isfinite(tvu_95_m)) c.sum_tvu_m += static_cast<float>(tvu_95_m);
    }
    c.sum_depth_m += static_cast<float>(depth_m);
    c.sum_elevation_m += elevation_m;
    c.sum_elevation2_m2 += elevation_m * elevation_m;
    const bool meets = MeetsTvu(c);
    if (met && !meets) ++tvu_failing_;
    if (!met && meets) --tvu_failing_;
    // A fresh stamp per tile per batch: no two tiles share a version, so a client that got
    // the tiles up to version V asks for the rest with since = V and misses none.
    if (tile.batch != batch || tile.version == 0) {
        tile.batch = batch;
        tile.version = ++stamp_;
    }
    ++soundings_;
    return first;
}

const GridCell* CoverageGrid::Cell(std::int64_t ix, std::int64_t iy) const {
    const std::int64_t tx = FloorDiv(ix, kTileCells), ty = FloorDiv(iy, kTileCells);
    auto it = tiles_.find(Key(tx, ty));
    if (it == tiles_.end()) return nullptr;
    const auto i = static_cast<std::size_t>(ix - tx * kTileCells);
    const auto j = static_cast<std::size_t>(iy - ty * kTileCells);
    return &it->second.cells[j * kTileCells + i];
}

bool CoverageGrid::Filled(std::int64_t ix, std::int64_t iy) const {
    const GridCell* c = Cell(ix, iy);
    return c != nullptr && c->count > 0;
}

bool CoverageGrid::IsHoliday(std::int64_t ix, std::int64_t iy) const {
    if (Filled(ix, iy)) return false;
    const int r = config_.holiday_search_cells;
    const auto covered_towards = [&](int dx, int dy) {
        for (int k = 1; k <= r; ++k) {
            if (Filled(ix + dx * k, iy + dy * k)) return true;
        }
        return false;
    };
    return (covered_towards(-1, 0) && covered_towards(1, 0)) ||
           (covered_towards(0, -1) && covered_towards(0, 1));
}

std::vector<std::pair<std::int64_t, std::int64_t>> CoverageGrid::Holidays(
    std::size_t limit, std::int64_t* total) const {
    std::vector<std::pair<std::int64_t, std::int64_t>> out;
    std::int64_t n = 0;
    // A cell of an absent tile cannot be a holiday: covered cells on both of its sides would
    // lie in two different tiles across its own 32-cell tile, 33 cells apart at least, and
    // holiday_search_cells <= kTileCells / 2 (Validate). So only the tiles' own cells are seen.
    for (const auto& [key, tile] : tiles_) {
        const std::int64_t x0 = static_cast<std::int64_t>(tile.tx) * kTileCells;
        const std::int64_t y0 = static_cast<std::int64_t>(tile.ty) * kTileCells;
        for (int j = 0; j < kTileCells; ++j) {
            for (int i = 0; i < kTileCells; ++i) {
                if (tile.cells[static_cast<std::size_t>(j) * kTileCells + i].count > 0) continue;
                if (IsHoliday(x0 + i, y0 + j)) {
                    ++n;
                    if (out.size() < limit) out.emplace_back(x0 + i, y0 + j);
                }
            }
        }
    }
    if (total) *total = n;
    return out;
}

CoverageStats CoverageGrid::Stats(bool with_holidays) const {
    CoverageStats s;
    s.soundings = soundings_;
    s.soundings_dropped = dropped_;
    s.filled_cells = filled_;
    s.tiles = static_cast<std::int64_t>(tiles_.size());
    s.cells_tvu_failing = tvu_failing_;
    s.soundings_tvu_over = tvu_over_;
    s.covered_area_m2 = static_cast<double>(filled_) * config_.cell_size_m * config_.cell_size_m;
    bool first = true;
    for (const auto& [key, tile] : tiles_) {
        if (tile.filled == 0) continue;
        for (int j = 0; j < kTileCells; ++j) {
            for (int i = 0; i < kTileCells; ++i) {
                const GridCell& c = tile.cells[static_cast<std::size_t>(j) * kTileCells + i];
                if (c.count == 0) continue;
                const double d = c.sum_depth_m / c.count;
                const std::int64_t ix = static_cast<std::int64_t>(tile.tx) * kTileCells + i;
                const std::int64_t iy = static_cast<std::int64_t>(tile.ty) * kTileCells + j;
                if (first) {
                    s.min_depth_m = s.max_depth_m = d;
                    s.min_ix = s.max_ix = ix;
                    s.min_iy = s.max_iy = iy;
                    first = false;
                }
                s.min_depth_m = std::min(s.min_depth_m, d);
                s.max_depth_m = std::max(s.max_depth_m, d);
                s.min_ix = std::min(s.min_ix, ix);
                s.max_ix = std::max(s.max_ix, ix);
                s.min_iy = std::min(s.min_iy, iy);
                s.max_iy = std::max(s.max_iy, iy);
            }
        }
    }
    if (with_holidays) Holidays(0, &s.holidays);
    return s;
}

std::vector<const GridTile*> CoverageGrid::TilesSince(std::uint64_t since) const {
    std::vector<const GridTile*> out;
    for (const auto& [key, tile] : tiles_) {
        if (tile.version > since) out.push_back(&tile);
    }
    std::sort(out.begin(), out.end(), [](const GridTile* a, const GridTile* b) {
        if (a->version != b->version) return a->version < b->version;
        return a->tx != b->tx ? a->tx < b->tx : a->ty < b->ty;
    });
    return out;
}

Expected<io::GridRaster> CoverageGrid::ToRaster(int utm_zone,
                                                bool northern,
                                                std::size_t max_cells) const {
    const CoverageStats s = Stats();
    if (s.filled_cells == 0) return Error{"the coverage grid is empty"};
    const std::int64_t nx = s.max_ix - s.min_ix + 1, ny = s.max_iy - s.min_iy + 1;
    if (static_cast<double>(nx) * static_cast<double>(ny) > static_cast<double>(max_cells)) {
        return Error{"the coverage grid spans " + std::to_string(nx) + " x " + std::to_string(ny) +
                     " cells, more than " + std::to_string(max_cells)};
    }
    io::GridRaster g;
    g.resolution_m = config_.cell_size_m;
    g.x0 = (static_cast<double>(s.min_ix) + 0.5) * config_.cell_size_m;
    g.y0 = (static_cast<double>(s.min_iy) + 0.5) * config_.cell_size_m;
    g.nx = static_cast<int>(nx);
    g.ny = static_cast<int>(ny);
    g.utm_zone = utm_zone;
    g.northern = northern;
    const auto n = static_cast<std::size_t>(nx * ny);
    // Overviews: counts by the nearest cell, the 0/1 flags by the mode (io::GridBandKind).
    using K = io::GridBandKind;
    const auto layer = [n](const char* name, const char* unit, K kind) {
        return io::GridLayer(name, unit, std::vector<float>(n, kNaN), kind);
    };
    g.layers = {layer("depth", "metre", K::kContinuous),
                layer("elevation", "metre", K::kContinuous),
                layer("elevation_stddev", "metre", K::kContinuous),
                layer("density", "count", K::kCount),
                layer("holiday", "", K::kClass),
                layer("tvu_95", "metre", K::kContinuous),
                layer("tvu_meets_order", "", K::kClass)};
    for (std::int64_t j = 0; j < ny; ++j) {
        for (std::int64_t i = 0; i < nx; ++i) {
            const auto k = static_cast<std::size_t>(j * nx + i);
            const std::int64_t ix = s.min_ix + i, iy = s.min_iy + j;
            const GridCell* c = Cell(ix, iy);
            if (c && c->count > 0) {
                const double m = c->sum_elevation_m / c->count;
                const double var = std::max(0.0, c->sum_elevation2_m2 / c->count - m * m);
                g.layers[0].values[k] = c->sum_depth_m / static_cast<float>(c->count);
                g.layers[1].values[k] = static_cast<float>(m);
                g.layers[2].values[k] = static_cast<float>(std::sqrt(var));
                g.layers[3].values[k] = static_cast<float>(c->count);
                g.layers[4].values[k] = 0.f;
                g.layers[5].values[k] = c->sum_tvu_m / static_cast<float>(c->count);
                g.layers[6].values[k] = MeetsTvu(*c) ? 1.f : 0.f;
            } else if (IsHoliday(ix, iy)) {
                g.layers[4].values[k] = 1.f;
            }
        }
    }
    g.metadata = {{"pitmap_product", "live coverage grid"},
                  {"pitmap_holiday_search_cells", std::to_string(config_.holiday_search_cells)},
                  {"pitmap_s44_order", hydro::ToString(order_)},
                  {"pitmap_tvu_limit",
                   "sqrt(" + std::to_string(limits_.tvu_a_m) + "^2 + (" +
                       std::to_string(limits_.tvu_b) + " d)^2) m at depth d"},
                  {"pitmap_tvu_min_share", std::to_string(config_.tvu_min_share)}};
    return g;
}

}  // namespace pitmap::proc::live
