// SPDX-License-Identifier: MIT
// CUBE by tiles (processor/hydro/cube.hpp RunCubeTile): a grid assembled from tiles, each
// computed alone from the soundings around it, equals the whole survey's grid node for node,
// bit for bit, for every disambiguation; with less overlap than CubeTileReach it does not
// (the comparison can fail); a tile far from the soundings is empty; bad arguments are refused.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>

#include "processor/hydro/cube.hpp"

namespace pitmap::proc::hydro {
namespace {

// A benched pit wall in UTM-sized coordinates (rounding at 5e6 m), with noise, a second
// surface of echoes over part of it and soundings of a few passes (times).
std::vector<CubeSounding> PitSoundings() {
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> u(0, 1);
    std::normal_distribution<double> n01(0, 1);
    std::vector<CubeSounding> s;
    const double e0 = 512345.37, n0 = 4912345.81;
    for (int k = 0; k < 60000; ++k) {
        CubeSounding q;
        const double x = 40 * u(rng), y = 30 * u(rng);
        q.x = e0 + x;
        q.y = n0 + y;
        // Benches 2 m high every 6 m, with a 60 deg face between them.
        const double bench = std::floor(x / 6.0);
        const double in = x - 6.0 * bench;
        const double face = in > 4.8 ? (in - 4.8) * std::tan(60 * M_PI / 180) : 0.0;
        q.z = -30 + 2.0 * bench + std::min(face, 2.0) + 0.05 * n01(rng);
        if (y > 10 && y < 14 && u(rng) < 0.3) q.z += 3.0;  // echoes above the floor
        q.sigma_v_m = 0.05f;
        q.sigma_h_m = 0.1f;
        q.depth_m = static_cast<float>(-q.z);
        q.sigma_common_m = k % 3 == 0 ? std::numeric_limits<float>::quiet_NaN() : 0.02f;
        q.time_s = static_cast<float>(k / 5000 * 40);
        s.push_back(q);
    }
    return s;
}

bool SameFloat(float a, float b) {
    return std::memcmp(&a, &b, sizeof a) == 0;
}

// The nodes of `tile` that differ from the same global nodes of `whole`.
int Differences(const CubeGrid& whole, const CubeGrid& tile) {
    int diff = 0;
    for (int j = 0; j < tile.ny; ++j) {
        for (int i = 0; i < tile.nx; ++i) {
            const std::size_t t = static_cast<std::size_t>(j) * tile.nx + i;
            const std::int64_t gi = tile.i0 + i - whole.i0, gj = tile.j0 + j - whole.j0;
            const std::size_t w = static_cast<std::size_t>(gj) * whole.nx + gi;
            if (!SameFloat(whole.elevation_m[w], tile.elevation_m[t]) ||
                !SameFloat(whole.uncertainty_m[w], tile.uncertainty_m[t]) ||
                !SameFloat(whole.density[w], tile.density[t]) ||
                !SameFloat(whole.hypotheses[w], tile.hypotheses[t])) {
                ++diff;
            }
        }
    }
    return diff;
}

// Tiles of `n` nodes over the survey's nodes: the differing nodes of all of them, and the filled
// nodes they hold.
int TiledDifferences(const std::vector<CubeSounding>& s,
                     const CubeConfig& config,
                     const CubeResult& whole,
                     int n,
                     double overlap_m,
                     std::int64_t* filled = nullptr) {
    const CubeGrid& g = whole.grid;
    const CubeNodeRange survey{g.i0, g.j0, g.i0 + g.nx, g.j0 + g.ny};
    int diff = 0;
    std::int64_t nodes_filled = 0;
    const auto floor_div = [](std::int64_t a, std::int64_t b) {
        return a >= 0 ? a / b : -((-a + b - 1) / b);
    };
    for (std::int64_t tj = floor_div(survey.j0, n); tj * n < survey.j1; ++tj) {
        for (std::int64_t ti = floor_div(survey.i0, n); ti * n < survey.i1; ++ti) {
            const CubeNodeRange core{std::max(survey.i0, ti * n),
                                     std::max(survey.j0, tj * n),
                                     std::min(survey.i1, (ti + 1) * n),
                                     std::min(survey.j1, (tj + 1) * n)};
            const CubeResult t = RunCubeTile(s, config, core, survey, overlap_m);
            EXPECT_TRUE(t.ok) << t.message;
            EXPECT_EQ(t.grid.nx, core.nx());
            EXPECT_EQ(t.grid.ny, core.ny());
            diff += Differences(g, t.grid);
            nodes_filled += t.nodes_filled;
        }
    }
    if (filled) *filled = nodes_filled;
    return diff;
}

TEST(CubeTile, TilesEqualTheWholeGridNodeForNode) {
    const std::vector<CubeSounding> s = PitSoundings();
    for (Disambiguation d :
         {Disambiguation::kPredictedSurface, Disambiguation::kLocale, Disambiguation::kDensity}) {
        SCOPED_TRACE(ToString(d));
        CubeConfig c;
        c.resolution_m = 0.3;  // not a binary fraction: node positions round
        c.disambiguation = d;
        c.num_threads = 2;
        const CubeResult whole = RunCube(s, c);
        ASSERT_TRUE(whole.ok) << whole.message;
        ASSERT_GT(whole.nodes_multiple, 100);  // the echoes made second hypotheses
        std::int64_t filled = 0;
        // 37 nodes (11.1 m): tiles meet the benches' faces at odd places.
        EXPECT_EQ(TiledDifferences(s, c, whole, 37, CubeTileReach(0.3, c), &filled), 0);
        EXPECT_EQ(filled, whole.nodes_filled);
    }
}

TEST(CubeTile, TooLittleOverlapChangesTheSeamNodes) {
    const std::vector<CubeSounding> s = PitSoundings();
    CubeConfig c;
    c.resolution_m = 0.3;
    c.num_threads = 2;
    const CubeResult whole = RunCube(s, c);
    ASSERT_TRUE(whole.ok);
    // Half a node of overlap: the soundings of the neighbouring cells (their predicted surface
    // and those that reach the edge nodes) are missing at every seam.
    EXPECT_GT(TiledDifferences(s, c, whole, 37, 0.15), 0);
}

TEST(CubeTile, LayOutMatchesRunCubeAndATileWithoutSoundingsIsEmpty) {
    const std::vector<CubeSounding> s = PitSoundings();
    CubeConfig c;
    c.resolution_m = 0.3;
    const CubeResult whole = RunCube(s, c);
    const CubeResult lay = LayOutCube(s, c);
    ASSERT_TRUE(lay.ok);
    EXPECT_EQ(lay.grid.i0, whole.grid.i0);
    EXPECT_EQ(lay.grid.j0, whole.grid.j0);
    EXPECT_EQ(lay.grid.nx, whole.grid.nx);
    EXPECT_EQ(lay.grid.ny, whole.grid.ny);
    EXPECT_TRUE(lay.grid.elevation_m.empty());
    const CubeNodeRange far{0, 0, 10, 10};
    const CubeResult t = RunCubeTile(s, c, far, far, CubeTileReach(0.3, c));
    ASSERT_TRUE(t.ok) << t.message;
    EXPECT_EQ(t.nodes_filled, 0);
    EXPECT_TRUE(std::isnan(t.grid.elevation_m[0]));
    // Without the survey's resolution, or without a core: refused, not a crash.
    CubeConfig auto_res = c;
    auto_res.resolution_m = 0;
    EXPECT_FALSE(RunCubeTile(s, auto_res, far, far, 5.0).ok);
    EXPECT_FALSE(RunCubeTile(s, c, CubeNodeRange{3, 3, 3, 9}, far, 5.0).ok);
}

}  // namespace
}  // namespace pitmap::proc::hydro
