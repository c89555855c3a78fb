// SPDX-License-Identifier: MIT
// CUBE by bands of node rows (processor/hydro/cube.hpp CubeLayout, PlanCubeBands, RunCubeTile;
// decision 035), as the grid stage runs it: the layout from soundings given one at a time is
// LayOutCube's; bands planned from the soundings counted by predicted-surface cell row, each
// gridded alone from the soundings of its cell rows (the halo of CubeTileCellRows) in input
// order, pasted, give RunCube's grid bit for bit, its counters and its message, for every
// disambiguation; a band given two cell rows less on each side does not (the halo is needed);
// the bands cover the rows once and keep to their budget where a cell allows.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include "processor/hydro/cube.hpp"

namespace pitmap::proc::hydro {
namespace {

// A benched pit floor and wall in UTM-sized coordinates, echoes over part of it, a few passes,
// and a few soundings CUBE does not take (NaN height, no sigma).
std::vector<CubeSounding> PitSoundings() {
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> u(0, 1);
    std::normal_distribution<double> n01(0, 1);
    std::vector<CubeSounding> s;
    const double e0 = 433210.61, n0 = 5102345.27;
    for (int k = 0; k < 50000; ++k) {
        CubeSounding q;
        const double x = 25 * u(rng), y = 45 * u(rng);
        q.x = e0 + x;
        q.y = n0 + y;
        const double bench = std::floor(y / 7.0);
        const double in = y - 7.0 * bench;
        const double face = in > 5.5 ? (in - 5.5) * std::tan(55 * M_PI / 180) : 0.0;
        q.z = -25 + 2.0 * bench + std::min(face, 2.0) + 0.04 * n01(rng);
        if (x > 8 && x < 12 && u(rng) < 0.3) q.z += 2.5;  // echoes above the floor
        q.sigma_v_m = 0.05f;
        q.sigma_h_m = 0.1f;
        q.depth_m = static_cast<float>(-q.z);
        q.sigma_common_m = k % 4 == 0 ? std::numeric_limits<float>::quiet_NaN() : 0.02f;
        q.sigma_h_common_m = 0.03f;
        q.time_s = static_cast<float>(k / 4000 * 35);
        if (k % 997 == 0) q.z = std::numeric_limits<double>::quiet_NaN();
        if (k % 1499 == 0) q.sigma_v_m = 0;
        s.push_back(q);
    }
    return s;
}

bool SameLayers(const CubeGrid& a, const CubeGrid& b) {
    const auto same = [](const std::vector<float>& x, const std::vector<float>& y) {
        return x.size() == y.size() &&
               std::memcmp(x.data(), y.data(), x.size() * sizeof(float)) == 0;
    };
    return same(a.elevation_m, b.elevation_m) && same(a.uncertainty_m, b.uncertainty_m) &&
           same(a.density, b.density) && same(a.hypotheses, b.hypotheses);
}

// The grid stage's way: the layout from the soundings one at a time, the soundings counted by
// cell row, the bands planned, each band's soundings (its cell rows grown by `grow` rows, the
// halo's) gridded alone and pasted. `bands`: how many.
CubeResult ByBands(const std::vector<CubeSounding>& s,
                   const CubeConfig& config,
                   std::int64_t max_soundings,
                   std::int64_t grow,
                   std::size_t* bands) {
    CubeLayout layout;
    for (const CubeSounding& q : s) layout.Add(q);
    CubeResult out = layout.Finish(config);
    if (!out.ok) return out;
    CubeGrid& g = out.grid;
    const double res = g.resolution_m;
    CubeConfig c = config;
    c.resolution_m = res;
    const double overlap = CubeTileReach(res, c);
    const std::int64_t first = CubeCellIndex(g.y0, res, c);
    std::vector<std::int64_t> counts(
        static_cast<std::size_t>(CubeCellIndex((g.j0 + g.ny) * res, res, c) - first + 1), 0);
    for (const CubeSounding& q : s) {
        if (CubeTakes(q)) ++counts[static_cast<std::size_t>(CubeCellIndex(q.y, res, c) - first)];
    }
    const std::vector<CubeBand> plan =
        PlanCubeBands(g, first, counts, c, overlap, max_soundings, 1'000'000);
    *bands = plan.size();
    const float nan = std::numeric_limits<float>::quiet_NaN();
    g.elevation_m.assign(g.size(), nan);
    g.uncertainty_m.assign(g.size(), nan);
    g.density.assign(g.size(), 0.0f);
    g.hypotheses.assign(g.size(), 0.0f);
    const CubeNodeRange survey{g.i0, g.j0, g.i0 + g.nx, g.j0 + g.ny};
    for (const CubeBand& band : plan) {
        std::vector<CubeSounding> mine;
        for (const CubeSounding& q : s) {
            if (!CubeTakes(q)) continue;
            const std::int64_t b = CubeCellIndex(q.y, res, c);
            if (b >= band.cells.first - grow && b <= band.cells.last + grow) mine.push_back(q);
        }
        // The tile's own halo, shrunk with `grow` < 0 (RunCubeTile reads what it is given).
        const double tile_overlap =
            overlap + static_cast<double>(grow) * res * c.predicted_surface_cells;
        const CubeResult t = RunCubeTile(mine, c, band.core, survey, std::max(0.0, tile_overlap));
        EXPECT_TRUE(t.ok) << t.message;
        for (int j = 0; j < t.grid.ny; ++j) {
            for (int i = 0; i < t.grid.nx; ++i) {
                const std::size_t from = static_cast<std::size_t>(j) * t.grid.nx + i;
                const std::size_t to =
                    static_cast<std::size_t>(t.grid.j0 - g.j0 + j) * g.nx + (t.grid.i0 - g.i0 + i);
                g.elevation_m[to] = t.grid.elevation_m[from];
                g.uncertainty_m[to] = t.grid.uncertainty_m[from];
                g.density[to] = t.grid.density[from];
                g.hypotheses[to] = t.grid.hypotheses[from];
            }
        }
        out.node_updates += t.node_updates;
        out.nodes_filled += t.nodes_filled;
        out.nodes_multiple += t.nodes_multiple;
        out.hypotheses_total += t.hypotheses_total;
    }
    out.message = DescribeCube(out);
    return out;
}

TEST(CubeBands, BandsOfTheLayoutGiveRunCubesGridCountersAndMessage) {
    const std::vector<CubeSounding> s = PitSoundings();
    for (Disambiguation d :
         {Disambiguation::kPredictedSurface, Disambiguation::kLocale, Disambiguation::kDensity}) {
        SCOPED_TRACE(ToString(d));
        CubeConfig c;
        c.resolution_m = 0;  // from the median depth, as the grid stage lays it out
        c.min_resolution_m = 0.3;
        c.disambiguation = d;
        c.num_threads = 2;
        const CubeResult whole = RunCube(s, c);
        ASSERT_TRUE(whole.ok) << whole.message;
        ASSERT_GT(whole.nodes_multiple, 50);      // the echoes made second hypotheses
        ASSERT_GT(whole.soundings_rejected, 10);  // and some soundings were not taken
        std::size_t bands = 0;
        const CubeResult banded = ByBands(s, c, 4000, 0, &bands);
        ASSERT_TRUE(banded.ok) << banded.message;
        EXPECT_GT(bands, 5U);
        EXPECT_TRUE(SameLayers(whole.grid, banded.grid));
        EXPECT_EQ(banded.grid.i0, whole.grid.i0);
        EXPECT_EQ(banded.grid.j0, whole.grid.j0);
        EXPECT_EQ(banded.median_depth_m, whole.median_depth_m);
        EXPECT_EQ(banded.capture_distance_m, whole.capture_distance_m);
        EXPECT_EQ(banded.soundings_used, whole.soundings_used);
        EXPECT_EQ(banded.soundings_rejected, whole.soundings_rejected);
        EXPECT_EQ(banded.node_updates, whole.node_updates);
        EXPECT_EQ(banded.nodes_filled, whole.nodes_filled);
        EXPECT_EQ(banded.nodes_multiple, whole.nodes_multiple);
        EXPECT_EQ(banded.hypotheses_total, whole.hypotheses_total);
        EXPECT_EQ(banded.message, whole.message);
    }
}

TEST(CubeBands, ABandWithoutItsHaloDiffersAtItsSeams) {
    const std::vector<CubeSounding> s = PitSoundings();
    CubeConfig c;
    c.min_resolution_m = 0.3;
    c.num_threads = 2;
    const CubeResult whole = RunCube(s, c);
    ASSERT_TRUE(whole.ok);
    std::size_t bands = 0;
    // Two cell rows less on each side than the halo RunCubeTile reads (one less still held
    // every sounding these seams' nodes read in this pit: CubeTileReach is a bound, with a node
    // of slack).
    const CubeResult banded = ByBands(s, c, 4000, -2, &bands);
    ASSERT_GT(bands, 5U);
    EXPECT_FALSE(SameLayers(whole.grid, banded.grid));
}

TEST(CubeBands, BandsCoverTheRowsOnceWithinTheirBudget) {
    CubeGrid g;
    g.resolution_m = 0.5;
    g.i0 = 100;
    g.j0 = -37;
    g.nx = 50;
    g.ny = 203;
    g.y0 = g.j0 * g.resolution_m;
    CubeConfig c;
    c.resolution_m = g.resolution_m;
    const double overlap = CubeTileReach(g.resolution_m, c);
    const std::int64_t first = CubeCellIndex(g.y0, g.resolution_m, c);
    const std::int64_t last = CubeCellIndex((g.j0 + g.ny) * g.resolution_m, g.resolution_m, c);
    std::vector<std::int64_t> counts(static_cast<std::size_t>(last - first + 1), 100);
    counts[20] = 5000;  // one cell over the budget alone: a band of its own rows
    const std::vector<CubeBand> bands =
        PlanCubeBands(g, first, counts, c, overlap, 1500, 1'000'000);
    ASSERT_GT(bands.size(), 3U);
    std::int64_t j = g.j0;
    for (const CubeBand& b : bands) {
        EXPECT_EQ(b.core.j0, j);
        EXPECT_GT(b.core.j1, b.core.j0);
        EXPECT_EQ(b.core.i0, g.i0);
        EXPECT_EQ(b.core.i1, g.i0 + g.nx);
        const CubeCellRows cells =
            CubeTileCellRows(b.core.j0, b.core.j1, g.resolution_m, c, overlap);
        EXPECT_EQ(b.cells.first, cells.first);
        EXPECT_EQ(b.cells.last, cells.last);
        // Over the budget only when a cell of rows is: then the band is that cell's rows.
        if (b.soundings > 1500) {
            EXPECT_LE(b.core.ny(), c.predicted_surface_cells);
        }
        j = b.core.j1;
    }
    EXPECT_EQ(j, g.j0 + g.ny);
    // Nodes bound the bands too.
    const std::vector<CubeBand> few_nodes =
        PlanCubeBands(g, first, counts, c, overlap, 1'000'000, 50 * 8);
    for (const CubeBand& b : few_nodes) EXPECT_LE(b.core.ny() * g.nx, 50 * 8);
    EXPECT_GE(few_nodes.size(), static_cast<std::size_t>(g.ny / 8));
}

}  // namespace
}  // namespace pitmap::proc::hydro
