// SPDX-License-Identifier: MIT
// The live coverage grid: binning, statistics, holidays (gaps inside the coverage, not its open
// edges), tile versions, and the raster a snapshot writes.
#include "processor/live/coverage_grid.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <tuple>

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
        for (int x = x0; x <= x1; ++x) g.Add(x + 0.5, y + 0.5, 100.0 - depth, depth, 0.1, v);
    }
}

TEST(CoverageGrid, BinsSoundingsIntoCellsWithMeans) {
    CoverageGrid g(Config(0.5));
    g.Add(10.1, 20.1, 90.0, 10.0, 0.1, 1);
    g.Add(10.4, 20.4, 92.0, 8.0, 0.1, 1);
    g.Add(10.6, 20.1, 95.0, 5.0, 0.1, 2);  // next cell east
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
    g.Add(-0.5, -33.5, 0, 1, 0.1, 1);
    g.Add(std::nan(""), 0, 0, 1, 0.1, 1);
    g.Add(0, 0, INFINITY, 1, 0.1, 1);
    g.Add(1e300, 0, 0, 1, 0.1, 1);
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
    g.Add(1, 1, 0, 1, 0.1, 1);   // tile (0, 0)
    g.Add(40, 1, 0, 1, 0.1, 2);  // tile (1, 0)
    g.Add(1, 40, 0, 1, 0.1, 3);  // tile (0, 1)
    g.Add(2, 2, 0, 1, 0.1, 4);   // tile (0, 0) again
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
    g.Add(3, 3, 0, 1, 0.1, 5);
    g.Add(41, 3, 0, 1, 0.1, 5);
    g.Add(3, 41, 0, 1, 0.1, 5);
    g.Add(4, 4, 0, 1, 0.1, 5);  // same batch, same tile: no new stamp
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
    g.Add(1, 1, 0, 1, 0.1, 1);
    g.Add(40, 1, 0, 1, 0.1, 1);
    g.Add(80, 1, 0, 1, 0.1, 1);
    g.Add(2, 2, 0, 1, 0.1, 1);
    EXPECT_EQ(g.num_tiles(), 2u);
    EXPECT_EQ(g.Stats().soundings, 3);
    EXPECT_EQ(g.Stats().soundings_dropped, 1);
}

TEST(CoverageGrid, RasterHoldsEveryLayer) {
    CoverageGrid g(Config(2.0, 2));
    g.Add(100.5, 200.5, 50.0, 10.0, 0.1, 1);
    g.Add(100.5, 200.5, 52.0, 8.0, 0.1, 1);
    g.Add(105.0, 200.5, 40.0, 20.0, 0.1, 1);  // two cells east: (52, 100); (51, 100) is a holiday
    auto r = g.ToRaster(29, true);
    ASSERT_TRUE(r) << r.error().message;
    EXPECT_EQ(r->nx, 3);
    EXPECT_EQ(r->ny, 1);
    EXPECT_DOUBLE_EQ(r->x0, 101.0);
    EXPECT_DOUBLE_EQ(r->y0, 201.0);
    ASSERT_EQ(r->layers.size(), 7u);
    EXPECT_EQ(r->layers[0].name, "depth");
    EXPECT_FLOAT_EQ(r->layers[0].values[0], 9.0f);
    EXPECT_FLOAT_EQ(r->layers[1].values[0], 51.0f);
    EXPECT_FLOAT_EQ(r->layers[2].values[0], 1.0f);
    EXPECT_FLOAT_EQ(r->layers[3].values[0], 2.0f);
    EXPECT_TRUE(std::isnan(r->layers[0].values[1]));
    EXPECT_FLOAT_EQ(r->layers[4].values[1], 1.0f);
    EXPECT_FLOAT_EQ(r->layers[4].values[2], 0.0f);
    EXPECT_EQ(r->layers[5].name, "tvu_95");
    EXPECT_FLOAT_EQ(r->layers[5].values[0], 0.1f);
    EXPECT_TRUE(std::isnan(r->layers[5].values[1]));
    EXPECT_EQ(r->layers[6].name, "tvu_meets_order");
    EXPECT_FLOAT_EQ(r->layers[6].values[0], 1.0f);  // 0.1 m is within every order's limit
    EXPECT_TRUE(std::isnan(r->layers[6].values[1]));
    bool order_named = false;
    for (const auto& [k, v] : r->metadata) order_named |= k == "pitmap_s44_order" && v == "1a";
    EXPECT_TRUE(order_named);
    EXPECT_FALSE(CoverageGrid(Config()).ToRaster(29, true));
    EXPECT_FALSE(g.ToRaster(29, true, 2));
}

TEST(CoverageGrid, ConfigValidation) {
    EXPECT_TRUE(Config().Validate().empty());
    EXPECT_FALSE(Config(0.0).Validate().empty());
    EXPECT_FALSE(Config(1.0, 17).Validate().empty());
    EXPECT_FALSE(Config(1.0, 0).Validate().empty());
    CoverageGridConfig c = Config();
    c.s44_order = "3";
    c.tvu_min_share = 0;
    c.cell_size_m = 0;
    const auto p = c.Validate();
    ASSERT_EQ(p.size(), 3u);  // every problem listed
    EXPECT_NE(p[1].find("s44_order"), std::string::npos);
    EXPECT_NE(p[1].find("\"3\""), std::string::npos);
    EXPECT_NE(p[2].find("tvu_min_share"), std::string::npos);
    for (const char* o : {"exclusive", "special", "1a", "1b", "2"}) {
        c = Config();
        c.s44_order = o;
        EXPECT_TRUE(c.Validate().empty()) << o;
    }
}

// S-44 Ed. 6.1 Table 1 TVU limits, by hand: sqrt(a^2 + (b d)^2).
//   1a (a 0.5, b 0.013) at 10 m: sqrt(0.25 + 0.0169) = 0.51662 m; at 40 m: sqrt(0.25 + 0.2704)
//   = 0.72139 m. special (a 0.25, b 0.0075) at 10 m: sqrt(0.0625 + 0.005625) = 0.26101 m.
//   2 (a 1.0, b 0.023) at 10 m: sqrt(1 + 0.0529) = 1.02611 m.
TEST(CoverageGrid, CountsSoundingsOverTheOrdersTvuLimitAtTheirDepth) {
    CoverageGrid g(Config());
    // Cell (0, 0) at 10 m: 0.516 m within, 0.517 m over.
    g.Add(0.5, 0.5, 90.0, 10.0, 0.516, 1);
    g.Add(0.5, 0.5, 90.0, 10.0, 0.517, 1);
    // Cell (1, 0) at 40 m: 0.72 m within (it would be over at 10 m).
    g.Add(1.5, 0.5, 60.0, 40.0, 0.72, 1);
    // Cell (2, 0): no TVU known counts as over.
    g.Add(2.5, 0.5, 90.0, 10.0, std::nan(""), 1);
    const GridCell* a = g.Cell(0, 0);
    const GridCell* b = g.Cell(1, 0);
    const GridCell* c = g.Cell(2, 0);
    ASSERT_TRUE(a && b && c);
    EXPECT_EQ(a->tvu_over, 1u);
    EXPECT_FLOAT_EQ(a->sum_tvu_m, 0.516f + 0.517f);
    EXPECT_EQ(b->tvu_over, 0u);
    EXPECT_EQ(c->tvu_over, 1u);
    EXPECT_FALSE(g.MeetsTvu(*a));  // 1 of 2 over: 50 % within < 95 %
    EXPECT_TRUE(g.MeetsTvu(*b));
    EXPECT_FALSE(g.MeetsTvu(*c));
    const CoverageStats s = g.Stats();
    EXPECT_EQ(s.cells_tvu_failing, 2);
    EXPECT_EQ(s.soundings_tvu_over, 2);

    // The same soundings held to order 2 all pass but the unknown one; to special, 0.516 m at
    // 10 m fails too (limit 0.261 m).
    for (const auto& [order, failing, over] :
         {std::tuple{"2", 1, 1}, std::tuple{"special", 3, 4}}) {
        CoverageGridConfig cfg = Config();
        cfg.s44_order = order;
        CoverageGrid h(cfg);
        h.Add(0.5, 0.5, 90.0, 10.0, 0.516, 1);
        h.Add(0.5, 0.5, 90.0, 10.0, 0.517, 1);
        h.Add(1.5, 0.5, 60.0, 40.0, 0.72, 1);
        h.Add(2.5, 0.5, 90.0, 10.0, std::nan(""), 1);
        EXPECT_EQ(h.Stats().cells_tvu_failing, failing) << order;
        EXPECT_EQ(h.Stats().soundings_tvu_over, over) << order;
    }
}

TEST(CoverageGrid, ACellMeetsTheOrderWithTheConfiguredShareWithin) {
    CoverageGrid g(Config());  // 95 %
    // 19 within, then 1 over: 19/20 = 95 % within, meets; a second over: 19/21 fails.
    for (int k = 0; k < 19; ++k) g.Add(0.5, 0.5, 90.0, 10.0, 0.2, 1);
    EXPECT_TRUE(g.Add(1.5, 0.5, 90.0, 10.0, 0.2, 1));  // first of its cell
    EXPECT_FALSE(g.Add(1.5, 0.5, 90.0, 10.0, 0.2, 1));
    EXPECT_EQ(g.Stats().cells_tvu_failing, 0);
    g.Add(0.5, 0.5, 90.0, 10.0, 0.9, 2);
    EXPECT_TRUE(g.MeetsTvu(*g.Cell(0, 0)));
    EXPECT_EQ(g.Stats().cells_tvu_failing, 0);
    g.Add(0.5, 0.5, 90.0, 10.0, 0.9, 2);
    EXPECT_FALSE(g.MeetsTvu(*g.Cell(0, 0)));
    EXPECT_EQ(g.Stats().cells_tvu_failing, 1);
    // Good soundings bring it back: 39 within of 41 = 95.1 %.
    for (int k = 0; k < 20; ++k) g.Add(0.5, 0.5, 90.0, 10.0, 0.2, 3);
    EXPECT_TRUE(g.MeetsTvu(*g.Cell(0, 0)));
    EXPECT_EQ(g.Stats().cells_tvu_failing, 0);
    // A share of 1: one sounding over fails the cell.
    CoverageGridConfig all = Config();
    all.tvu_min_share = 1.0;
    CoverageGrid h(all);
    for (int k = 0; k < 100; ++k) h.Add(0.5, 0.5, 90.0, 10.0, 0.2, 1);
    h.Add(0.5, 0.5, 90.0, 10.0, 0.6, 1);
    EXPECT_EQ(h.Stats().cells_tvu_failing, 1);
}

}  // namespace
}  // namespace pitmap::proc::live
