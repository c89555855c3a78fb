// SPDX-License-Identifier: MIT
#include "tools/sim/world.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace pitmap::sim {
namespace {

TerrainGrid FlatGrid(double z, double half = 50, double res = 0.5) {
    TerrainGrid g;
    g.resolution_m = res;
    g.x0_m = g.y0_m = -half;
    g.nx = g.ny = static_cast<int>(2 * half / res) + 1;
    g.height_m.assign(static_cast<std::size_t>(g.nx * g.ny), static_cast<float>(z));
    return g;
}

TEST(Scenario, BuiltinsAreValidAndNamed) {
    for (const auto& name : BuiltinScenarioNames()) {
        auto s = BuiltinScenario(name);
        ASSERT_TRUE(s.ok()) << name;
        EXPECT_EQ(s->name, name);
        EXPECT_TRUE(s->Validate().empty()) << name;
    }
    EXPECT_NEAR(BuiltinScenario("bejanca")->track.duration_s * 10, 12786, 1e-6);
    EXPECT_NEAR(BuiltinScenario("gps-outage")->track.duration_s * 10, 7291, 1e-6);
}

TEST(Scenario, UnknownNameListsTheValidOnes) {
    auto s = BuiltinScenario("bejenca");
    ASSERT_FALSE(s.ok());
    EXPECT_NE(s.error().message.find("demo, bejanca, gps-outage"), std::string::npos);
}

TEST(Scenario, ValidateListsEveryProblem) {
    ScenarioConfig s;
    s.pit.max_depth_m = -1;
    s.sonar.num_beams = 1000;
    s.nav.outages_s = {10.0};
    s.boresight_deg = {1.0};
    EXPECT_GE(s.Validate().size(), 4u);
}

TEST(PitWorld, BejancaShapeMatchesTheScenario) {
    const PitConfig pit = BuiltinScenario("bejanca")->pit;
    const PitWorld world(pit, 1919);
    // Water line: the height crosses zero at the shore along both axes.
    EXPECT_NEAR(world.Height(pit.half_length_m, 0.0), 0.0, 0.25);
    EXPECT_NEAR(world.Height(0.0, pit.half_width_m), 0.0, 0.25);
    EXPECT_GT(world.Height(pit.half_length_m + 3, 0.0), 0.5);  // land
    // Centre: the backfilled floor, within its mound amplitude.
    EXPECT_NEAR(world.Depth(0, 0), pit.floor_depth_m, pit.backfill_amplitude_m + 0.5);
    double deepest = 0;
    for (const float h : world.grid().height_m)
        deepest = std::max(deepest, -static_cast<double>(h));
    EXPECT_LE(deepest, pit.max_depth_m + 1e-6);
    EXPECT_GT(deepest, pit.floor_depth_m);
    // Benches: walking in from the shore, depth rises in steps: some flat-ish treads exist.
    int flat = 0;
    for (double x = pit.half_length_m - 1; x > pit.half_length_m - 30; x -= 0.5) {
        if (world.Gradient(x, 0).norm() < 0.25) ++flat;
    }
    EXPECT_GT(flat, 10);
    EXPECT_GT(world.max_slope(), 1.0);  // the walls are steep
}

TEST(PitWorld, DeterministicFromTheSeed) {
    const PitConfig pit = BuiltinScenario("demo")->pit;
    const PitWorld a(pit, 5), b(pit, 5), c(pit, 6);
    EXPECT_EQ(a.grid().height_m, b.grid().height_m);
    EXPECT_NE(a.grid().height_m, c.grid().height_m);
}

TEST(PitWorld, RayCastOnAFlatFloor) {
    const PitWorld world(FlatGrid(-10.0));
    const Eigen::Vector3d o(0, 0, -0.25);
    auto r = world.RayCast(o, Eigen::Vector3d(0, 0, -1), 100.0);
    ASSERT_TRUE(r);
    EXPECT_NEAR(*r, 9.75, 1e-4);
    const double a = 50.0 * 3.14159265358979323846 / 180.0;
    r = world.RayCast(o, Eigen::Vector3d(std::sin(a), 0, -std::cos(a)), 100.0);
    ASSERT_TRUE(r);
    EXPECT_NEAR(*r, 9.75 / std::cos(a), 1e-4);
    EXPECT_FALSE(world.RayCast(o, Eigen::Vector3d(0, 0, -1), 5.0));             // out of range
    EXPECT_FALSE(world.RayCast(o, Eigen::Vector3d(1, 0, 0), 100.0));            // horizontal: never
    EXPECT_FALSE(world.RayCast({0, 0, -20}, Eigen::Vector3d(0, 0, 1), 100.0));  // starts below
}

TEST(PitWorld, RayCastAgreesWithFineMarchingOnThePit) {
    const PitConfig pit = BuiltinScenario("bejanca")->pit;
    const PitWorld world(pit, 3);
    const Eigen::Vector3d o(20, 10, -0.3);
    for (double deg = -60; deg <= 60; deg += 7.5) {
        const double a = deg * 3.14159265358979323846 / 180.0;
        const Eigen::Vector3d d(std::sin(a), 0.1, -std::cos(a));
        const Eigen::Vector3d dir = d.normalized();
        auto r = world.RayCast(o, dir, 100.0);
        // Reference: 1 mm steps to the first crossing.
        double ref = std::numeric_limits<double>::quiet_NaN();
        for (double t = 0; t < 100; t += 0.001) {
            const Eigen::Vector3d q = o + t * dir;
            if (q.z() <= world.Height(q.x(), q.y())) {
                ref = t;
                break;
            }
        }
        ASSERT_TRUE(r) << deg;
        EXPECT_NEAR(*r, ref, 0.002) << deg;
    }
}

TEST(PitWorld, SignedDistanceOnAFlatFloorAndAWall) {
    const PitWorld flat(FlatGrid(-10.0));
    EXPECT_NEAR(flat.SignedDistance({3, 4, -9.0}), 1.0, 1e-9);
    EXPECT_NEAR(flat.SignedDistance({3, 4, -10.5}), -0.5, 1e-9);

    // A 45-degree plane z = x - 20: the distance of (0, 0, 0) is 20 / sqrt(2).
    TerrainGrid g = FlatGrid(0.0, 40, 0.5);
    for (int iy = 0; iy < g.ny; ++iy)
        for (int ix = 0; ix < g.nx; ++ix)
            g.height_m[static_cast<std::size_t>(iy * g.nx + ix)] =
                static_cast<float>(g.x0_m + ix * g.resolution_m - 20.0);
    const PitWorld slope(g);
    EXPECT_NEAR(slope.SignedDistance({0, 0, 0}), 20.0 / std::sqrt(2.0), 1e-6);
    EXPECT_NEAR(slope.Normal(1, 1).dot(Eigen::Vector3d(-1, 0, 1).normalized()), 1.0, 1e-9);
}

TEST(PitWorld, SignedDistanceNearBenchEdgesMatchesBruteForce) {
    const PitConfig pit = BuiltinScenario("bejanca")->pit;
    const PitWorld world(pit, 11);
    // Points 0.3 m off the surface around the first wall along +x.
    for (double x = pit.half_length_m - 14; x < pit.half_length_m - 2; x += 1.3) {
        const Eigen::Vector3d s(x, 2.0, world.Height(x, 2.0));
        const Eigen::Vector3d p = s + 0.3 * world.Normal(x, 2.0);
        double best = 1e9;
        for (double dx = -1.0; dx <= 1.0; dx += 0.01)
            for (double dy = -0.5; dy <= 0.5; dy += 0.05) {
                const Eigen::Vector3d q(
                    p.x() + dx, p.y() + dy, world.Height(p.x() + dx, p.y() + dy));
                best = std::min(best, (p - q).norm());
            }
        EXPECT_NEAR(world.SignedDistance(p), best, 0.02) << x;
    }
}

}  // namespace
}  // namespace pitmap::sim
