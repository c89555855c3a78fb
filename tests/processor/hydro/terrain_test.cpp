// SPDX-License-Identifier: MIT
// The mine-planning layers (processor/hydro/terrain.hpp) on synthetic DEMs of known shape:
// planes of known slope, a boulder of known height, noise of known spread, a wall with a gap
// the crawler must find, holes in the survey, and the configuration's problems.
#include "processor/hydro/terrain.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <random>

namespace pitmap::proc::hydro {
namespace {

constexpr double kPi = 3.14159265358979323846;

struct Dem {
    int nx, ny;
    double res;
    std::vector<float> h;
    TerrainGrid Grid() const { return TerrainGrid{500000.0, 6000000.0, res, nx, ny, &h}; }
    float& At(int i, int j) { return h[static_cast<std::size_t>(j) * nx + i]; }
    std::size_t K(int i, int j) const { return static_cast<std::size_t>(j) * nx + i; }
};

Dem MakeDem(int nx, int ny, double res, const std::function<double(double, double)>& z) {
    Dem d{nx, ny, res, std::vector<float>(static_cast<std::size_t>(nx) * ny)};
    for (int j = 0; j < ny; ++j) {
        for (int i = 0; i < nx; ++i) d.At(i, j) = static_cast<float>(z(i * res, j * res));
    }
    return d;
}

TerrainClass ClassAt(const TerrainResult& r, const Dem& d, int i, int j) {
    return static_cast<TerrainClass>(static_cast<int>(r.terrain_class[d.K(i, j)]));
}

TEST(Terrain, APlaneHasItsSlopeNoRoughnessAndNoStep) {
    for (double deg : {0.0, 5.0, 12.0, 35.0}) {
        const double g = std::tan(deg * kPi / 180);
        // Tilted along a diagonal direction so both gradient components count.
        const Dem d = MakeDem(
            60, 50, 0.1, [&](double x, double y) { return -30.0 + g * (0.6 * x + 0.8 * y); });
        const TerrainResult r = ComputeTerrain(d.Grid(), TerrainConfig{});
        for (int j : {0, 10, 25, 49}) {
            for (int i : {0, 7, 30, 59}) {
                EXPECT_NEAR(r.slope_deg[d.K(i, j)], deg, 0.01) << deg << " at " << i << "," << j;
                EXPECT_LT(r.roughness_m[d.K(i, j)], 1e-3);
                EXPECT_LT(r.step_m[d.K(i, j)], 1e-3);
            }
        }
        const TerrainClass want = deg <= 20 ? TerrainClass::kTraversable : TerrainClass::kTooSteep;
        EXPECT_EQ(ClassAt(r, d, 30, 25), want) << deg;
    }
}

TEST(Terrain, NoiseGivesItsSpreadAsRoughness) {
    std::mt19937 rng(7);
    std::normal_distribution<double> noise(0.0, 0.05);
    const Dem d =
        MakeDem(80, 80, 0.1, [&](double x, double) { return -20.0 + 0.1 * x + noise(rng); });
    TerrainConfig c;
    c.window_m = 2.0;  // 21 x 21 nodes: the spread well estimated
    const TerrainResult r = ComputeTerrain(d.Grid(), c);
    double sum = 0;
    int n = 0;
    for (int j = 20; j < 60; ++j) {
        for (int i = 20; i < 60; ++i) {
            sum += r.roughness_m[d.K(i, j)];
            ++n;
        }
    }
    EXPECT_NEAR(sum / n, 0.05, 0.003);
    EXPECT_NEAR(r.slope_deg[d.K(40, 40)], std::atan(0.1) * 180 / kPi, 1.0);
}

TEST(Terrain, ABoulderIsAStepObstacleAndItsSurroundsAreNot) {
    // A flat floor on a 10 deg slope, with a 0.6 m boulder 0.6 m square at (3, 3) m.
    const double g = std::tan(10 * kPi / 180);
    const Dem d = MakeDem(60, 60, 0.1, [&](double x, double y) {
        const bool boulder = std::abs(x - 3.0) <= 0.3 && std::abs(y - 3.0) <= 0.3;
        return -40.0 + g * x + (boulder ? 0.6 : 0.0);
    });
    const TerrainResult r = ComputeTerrain(d.Grid(), TerrainConfig{});
    EXPECT_GT(r.step_m[d.K(27, 30)], 0.55);  // at its edge
    EXPECT_LT(r.step_m[d.K(30, 30)], 0.1);   // its flat top holds no edge within 0.5 m ...
    EXPECT_EQ(ClassAt(r, d, 30, 30), TerrainClass::kStep);  // ... but the crawler's body would
    EXPECT_EQ(ClassAt(r, d, 27, 30), TerrainClass::kStep);
    EXPECT_EQ(ClassAt(r, d, 21, 30), TerrainClass::kStep);         // 0.3 m from the edge
    EXPECT_EQ(ClassAt(r, d, 17, 30), TerrainClass::kTraversable);  // 0.7 m from it
    EXPECT_LT(r.step_m[d.K(5, 5)], 1e-3);                          // 2.5 m away: a plain slope
    EXPECT_NEAR(r.slope_deg[d.K(5, 5)], 10.0, 0.01);
    EXPECT_EQ(ClassAt(r, d, 5, 5), TerrainClass::kTraversable);
    TerrainConfig climber;
    climber.crawler_max_step_m = 0.8;  // a crawler that climbs it
    climber.crawler_max_roughness_m = 1.0;
    climber.crawler_max_slope_deg = 60;
    const TerrainResult r2 = ComputeTerrain(d.Grid(), climber);
    EXPECT_EQ(ClassAt(r2, d, 27, 30), TerrainClass::kTraversable);
}

TEST(Terrain, TheReachableAreaGoesThroughTheGapOnly) {
    // A floor split at x = 4 m by a 1 m high ridge; the ridge has a 1.5 m gap at y in [2, 3.5] m
    // unless `closed`.
    const auto floor = [](bool closed) {
        return MakeDem(80, 60, 0.1, [closed](double x, double y) {
            const bool ridge = std::abs(x - 4.0) <= 0.2 && (closed || y < 2.0 || y > 3.5);
            return -10.0 + (ridge ? 1.0 : 0.0);
        });
    };
    TerrainConfig c;
    c.launch_easting = 500000.0 + 1.0;  // (1, 3) m into the grid: west of the ridge
    c.launch_northing = 6000000.0 + 3.0;
    const Dem open = floor(false);
    const TerrainResult r = ComputeTerrain(open.Grid(), c);
    ASSERT_TRUE(r.launch_found) << r.message;
    EXPECT_EQ(ClassAt(r, open, 10, 30), TerrainClass::kReachable);
    EXPECT_EQ(ClassAt(r, open, 70, 5), TerrainClass::kReachable);  // east, through the gap
    EXPECT_EQ(ClassAt(r, open, 40, 5), TerrainClass::kStep);       // the ridge itself

    const Dem closed = floor(true);
    const TerrainResult r2 = ComputeTerrain(closed.Grid(), c);
    ASSERT_TRUE(r2.launch_found);
    EXPECT_EQ(ClassAt(r2, closed, 10, 30), TerrainClass::kReachable);
    EXPECT_EQ(ClassAt(r2, closed, 70, 5), TerrainClass::kTraversable);  // cut off
    EXPECT_LT(r2.nodes_by_class[static_cast<int>(TerrainClass::kReachable)],
              r.nodes_by_class[static_cast<int>(TerrainClass::kReachable)]);
    EXPECT_NE(r2.message.find("reachable from the launch point"), std::string::npos);
}

TEST(Terrain, ALaunchPointFarFromTraversableGroundReachesNothing) {
    const Dem d = MakeDem(40, 40, 0.1, [](double x, double) { return -10.0 + x; });  // 45 deg
    TerrainConfig c;
    c.launch_easting = 500000.0 + 2.0;
    c.launch_northing = 6000000.0 + 2.0;
    const TerrainResult r = ComputeTerrain(d.Grid(), c);
    EXPECT_TRUE(r.launch_given);
    EXPECT_FALSE(r.launch_found);
    EXPECT_EQ(r.nodes_by_class[static_cast<int>(TerrainClass::kReachable)], 0);
    EXPECT_NE(r.message.find("no traversable node"), std::string::npos) << r.message;
}

TEST(Terrain, HolesAreNoDataAndSparseWindowsAreNotGuessed) {
    Dem d = MakeDem(40, 40, 0.1, [](double, double) { return -10.0; });
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (int j = 0; j < 40; ++j) {
        for (int i = 0; i < 40; ++i) {
            if (i >= 20 && (i + j) % 3 != 0) d.At(i, j) = nan;  // east half: one node in three
        }
    }
    const TerrainResult r = ComputeTerrain(d.Grid(), TerrainConfig{});  // min_fill 0.5
    EXPECT_EQ(ClassAt(r, d, 5, 20), TerrainClass::kTraversable);
    EXPECT_EQ(ClassAt(r, d, 30, 20), TerrainClass::kNoData);  // has a height, too few around
    EXPECT_TRUE(std::isnan(r.slope_deg[d.K(30, 20)]));
    EXPECT_TRUE(std::isnan(r.slope_deg[d.K(31, 20)]));  // no height at all
    EXPECT_GT(r.nodes_with_data, 0);
}

TEST(Terrain, EveryConfigProblemIsListed) {
    TerrainConfig c;
    c.window_m = 0;
    c.min_fill = 2;
    c.crawler_max_slope_deg = 95;
    c.crawler_max_step_m = -1;
    c.launch_easting = 1;  // without the northing
    const auto problems = c.Validate();
    EXPECT_EQ(problems.size(), 6u);  // step_window_m > window_m = 0 is one more
    EXPECT_TRUE(TerrainConfig{}.Validate().empty());
}

}  // namespace
}  // namespace pitmap::proc::hydro
