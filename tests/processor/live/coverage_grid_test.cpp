// SPDX-License-Identifier: MIT
// The live coverage grid: binning, statistics, holidays (gaps inside the coverage, not its open
// edges), tile versions, and the raster a snapshot writes.
#include "processor/live/coverage_grid.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace pitmap::proc::live {
namespace {

CoverageGridConfig Config(double cell = 1.0, int search = 3) {
    CoverageGridConfig c;
    c.cell_size_m = cell;
    c.holiday_search_cells = search;
    return c;
}

// Fills cells [x0, x1] x [y0, y1] (cell indices, cell size 1) with one sounding each.
void Fill(CoverageGrid& g, int x0, int x1, int y0, int y1, double depth, std::uint64_t v) {
    for (int y = y0; y <= y1; ++y) {
        for (int x = x0; x <= x1; ++x) g.Add(x + 0.5, y + 0.5, 100.0 - depth, depth, v);
    }
}

TEST(CoverageGrid, BinsSoundingsIntoCellsWithMeans) {
    CoverageGrid g(Config(0.5));
    g.Add(10.1, 20.1, 90.0, 10.0, 1);
    g.Add(10.4, 20.4, 92.0, 8.0, 1);
    g.Add(10.6, 20.1, 95.0, 5.0, 2);  // next cell east
    const CoverageStats s = g.Stats();
    EXPECT_EQ(s.soundings, 3);
    EXPECT_EQ(s.filled_cells, 2);
    EXPECT_DOUBLE_EQ(s.covered_area_m2, 0.5);
    EXPECT_DOUBLE_EQ(s.min_depth_m, 5.0);
    EXPECT_DOUBLE_EQ(s.max_depth_m, 9.0);
    const GridCell* c = g.Cell(20, 40);
    ASSERT_NE(c, nullptr);
    EXPECT_EQ(c->count, 2u);
    EXPECT_DOUBLE_EQ(c->sum_elevation_m / c->count, 91.0);
}

TEST(CoverageGrid, NegativeCoordinatesAndNonFiniteInput) {
    CoverageGrid g(Config());
    g.Add(-0.5, -33.5, 0, 1, 1);
    g.Add(std::nan(""), 0, 0, 1, 1);
    g.Add(0, 0, INFINITY, 1, 1);
    g.Add(1e300, 0, 0, 1, 1);
    const CoverageStats s = g.Stats();
    EXPECT_EQ(s.soundings, 1);
    EXPECT_EQ(s.soundings_dropped, 3);
    EXPECT_EQ(s.min_ix, -1);
    EXPECT_EQ(s.min_iy, -34);
    ASSERT_NE(g.Cell(-1, -34), nullptr);
    EXPECT_EQ(g.Cell(-1, -34)->count, 1u);
}

TEST(CoverageGrid, HolidaysAreGapsInsideTheCoverageNotItsEdges) {
    CoverageGrid g(Config(1.0, 3));
    // Two swaths along y, x in [0, 9] and [12, 21], with a 2-cell gap between them, and one
    // missing cell inside the first swath.
    Fill(g, 0, 9, 0, 19, 10.0, 1);
    Fill(g, 12, 21, 0, 19, 10.0, 2);
    EXPECT_TRUE(g.IsHoliday(10, 5));
    EXPECT_TRUE(g.IsHoliday(11, 5));
    EXPECT_FALSE(g.IsHoliday(-1, 5));  // the open west edge
    EXPECT_FALSE(g.IsHoliday(5, 20));  // beyond the northern end
    EXPECT_FALSE(g.IsHoliday(22, 5));  // the open east edge
    std::int64_t total = 0;
    auto list = g.Holidays(1000, &total);
    EXPECT_EQ(total, 2 * 20);  // the gap's two columns along the whole swath length
    EXPECT_EQ(list.size(), 40u);
    // A gap wider than the search distance is not a holiday (two separate areas).
    CoverageGrid wide(Config(1.0, 3));
    Fill(wide, 0, 9, 0, 9, 10.0, 1);
    Fill(wide, 17, 26, 0, 9, 10.0, 1);
    EXPECT_FALSE(wide.IsHoliday(13, 5));
    EXPECT_EQ(wide.Stats().holidays, 0);
    // Limit: the list is cut, the total is not.
    list = g.Holidays(5, &total);
    EXPECT_EQ(list.size(), 5u);
    EXPECT_EQ(total, 40);
}

TEST(CoverageGrid, HolidayAcrossATileBorder) {
    CoverageGrid g(Config(1.0, 2));
    // A single missing cell at x = 32 (the first cell of the next tile), covered either side.
    Fill(g, 29, 31, 0, 2, 5.0, 1);
    Fill(g, 33, 35, 0, 2, 5.0, 1);
    EXPECT_TRUE(g.IsHoliday(32, 1));
    EXPECT_EQ(g.Stats().holidays, 3);
}

TEST(CoverageGrid, TilesSinceReturnsOnlyChangedTilesOldestFirst) {
    CoverageGrid g(Config());
    g.Add(1, 1, 0, 1, 1);   // tile (0, 0)
    g.Add(40, 1, 0, 1, 2);  // tile (1, 0)
    g.Add(1, 40, 0, 1, 3);  // tile (0, 1)
    g.Add(2, 2, 0, 1, 4);   // tile (0, 0) again
    auto t = g.TilesSince(0);
    ASSERT_EQ(t.size(), 3u);
    EXPECT_EQ(t[0]->version, 2u);
    EXPECT_EQ(t[2]->version, 4u);
    EXPECT_EQ(t[2]->tx, 0);
    EXPECT_EQ(t[2]->ty, 0);
    EXPECT_EQ(g.version(), 4u);
    t = g.TilesSince(3);
    ASSERT_EQ(t.size(), 1u);
    EXPECT_EQ(t[0]->filled, 2);
    EXPECT_TRUE(g.TilesSince(4).empty());
    // One batch touching three tiles stamps each with its own version.
    g.Add(3, 3, 0, 1, 5);
    g.Add(41, 3, 0, 1, 5);
    g.Add(3, 41, 0, 1, 5);
    g.Add(4, 4, 0, 1, 5);  // same batch, same tile: no new stamp
    t = g.TilesSince(4);
    ASSERT_EQ(t.size(), 3u);
    EXPECT_EQ(t[0]->version, 5u);
    EXPECT_EQ(t[1]->version, 6u);
    EXPECT_EQ(t[2]->version, 7u);
    EXPECT_EQ(g.version(), 7u);
}

TEST(CoverageGrid, MaxTilesBoundsMemoryAndCountsTheRest) {
    CoverageGridConfig c = Config();
    c.max_tiles = 2;
    CoverageGrid g(c);
    g.Add(1, 1, 0, 1, 1);
    g.Add(40, 1, 0, 1, 1);
    g.Add(80, 1, 0, 1, 1);
    g.Add(2, 2, 0, 1, 1);
    EXPECT_EQ(g.num_tiles(), 2u);
    EXPECT_EQ(g.Stats().soundings, 3);
    EXPECT_EQ(g.Stats().soundings_dropped, 1);
}

TEST(CoverageGrid, RasterHoldsEveryLayer) {
    CoverageGrid g(Config(2.0, 2));
    g.Add(100.5, 200.5, 50.0, 10.0, 1);
    g.Add(100.5, 200.5, 52.0, 8.0, 1);
    g.Add(105.0, 200.5, 40.0, 20.0, 1);  // two cells east: (52, 100); (51, 100) is a holiday
    auto r = g.ToRaster(29, true);
    ASSERT_TRUE(r) << r.error().message;
    EXPECT_EQ(r->nx, 3);
    EXPECT_EQ(r->ny, 1);
    EXPECT_DOUBLE_EQ(r->x0, 101.0);
    EXPECT_DOUBLE_EQ(r->y0, 201.0);
    ASSERT_EQ(r->layers.size(), 5u);
    EXPECT_EQ(r->layers[0].name, "depth");
    EXPECT_FLOAT_EQ(r->layers[0].values[0], 9.0f);
    EXPECT_FLOAT_EQ(r->layers[1].values[0], 51.0f);
    EXPECT_FLOAT_EQ(r->layers[2].values[0], 1.0f);
    EXPECT_FLOAT_EQ(r->layers[3].values[0], 2.0f);
    EXPECT_TRUE(std::isnan(r->layers[0].values[1]));
    EXPECT_FLOAT_EQ(r->layers[4].values[1], 1.0f);
    EXPECT_FLOAT_EQ(r->layers[4].values[2], 0.0f);
    EXPECT_FALSE(CoverageGrid(Config()).ToRaster(29, true));
    EXPECT_FALSE(g.ToRaster(29, true, 2));
}

TEST(CoverageGrid, ConfigValidation) {
    EXPECT_TRUE(Config().Validate().empty());
    EXPECT_FALSE(Config(0.0).Validate().empty());
    EXPECT_FALSE(Config(1.0, 17).Validate().empty());
    EXPECT_FALSE(Config(1.0, 0).Validate().empty());
}

}  // namespace
}  // namespace pitmap::proc::live
