// SPDX-License-Identifier: MIT
#include "tools/sim/world.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <vector>

namespace pitmap::sim {
namespace {

// GridHash of the demo and bejanca terrains as written before the quarry features existed
// (their terrain.f32 files are byte-identical to those of the previous commit).
constexpr std::uint64_t kDemoGridHash = 11867582445806495511ull;
constexpr std::uint64_t kBejancaGridHash = 15635044643398198824ull;

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

// FNV-1a over the float bits of a grid: pins the terrain of scenarios that must not change.
std::uint64_t GridHash(const TerrainGrid& g) {
    std::uint64_t h = 0xcbf29ce484222325ull;
    for (const float v : g.height_m) {
        std::uint32_t bits;
        std::memcpy(&bits, &v, 4);
        for (int i = 0; i < 4; ++i) {
            h ^= (bits >> (8 * i)) & 0xFFu;
            h *= 0x100000001b3ull;
        }
    }
    return h;
}

TEST(PitWorld, DemoAndBejancaTerrainsAreUnchangedByTheQuarryFeatures) {
    // Values of the terrain before the high wall, ramp and boulders existed (the features are
    // off in these scenarios and must not move a single height).
    const ScenarioConfig demo = *BuiltinScenario("demo");
    const ScenarioConfig bejanca = *BuiltinScenario("bejanca");
    EXPECT_EQ(GridHash(PitWorld(demo.pit, demo.seed).grid()), kDemoGridHash);
    EXPECT_EQ(GridHash(PitWorld(bejanca.pit, bejanca.seed).grid()), kBejancaGridHash);
}

class Quarry : public ::testing::Test {
protected:
    static void SetUpTestSuite() {
        sc_ = new ScenarioConfig(*BuiltinScenario("quarry"));
        world_ = new PitWorld(sc_->pit, sc_->seed);
    }
    static void TearDownTestSuite() {
        delete world_;
        delete sc_;
    }
    // Height of the grid cell nearest to (x, y): the truth grid itself, no interpolation.
    static double Cell(const TerrainGrid& g, double x, double y) {
        const int ix =
            std::clamp(static_cast<int>(std::lround((x - g.x0_m) / g.resolution_m)), 0, g.nx - 1);
        const int iy =
            std::clamp(static_cast<int>(std::lround((y - g.y0_m) / g.resolution_m)), 0, g.ny - 1);
        return g.height_m[static_cast<std::size_t>(iy) * static_cast<std::size_t>(g.nx) +
                          static_cast<std::size_t>(ix)];
    }
    // Least-squares slope dz/ds of the points (s, z).
    static double FitSlope(const std::vector<double>& s, const std::vector<double>& z) {
        double ms = 0, mz = 0;
        for (std::size_t i = 0; i < s.size(); ++i) ms += s[i], mz += z[i];
        ms /= static_cast<double>(s.size());
        mz /= static_cast<double>(z.size());
        double sxy = 0, sxx = 0;
        for (std::size_t i = 0; i < s.size(); ++i) {
            sxy += (s[i] - ms) * (z[i] - mz);
            sxx += (s[i] - ms) * (s[i] - ms);
        }
        return sxy / sxx;
    }
    static ScenarioConfig* sc_;
    static PitWorld* world_;
};
ScenarioConfig* Quarry::sc_ = nullptr;
PitWorld* Quarry::world_ = nullptr;

constexpr double kPi = 3.14159265358979323846;

TEST_F(Quarry, HasAHighWallSteeperThan60Deg) {
    const TerrainGrid& g = world_->grid();
    // Profiles straight down the north face (the high wall's sector), every 2 m along it: the
    // face from 2 m to 12 m depth, fitted by a line, is steeper than 60 deg.
    int steep_profiles = 0;
    for (double x = -10; x <= 10; x += 2) {
        std::vector<double> s, z;
        for (double y = sc_->pit.half_width_m + 2; y > 0; y -= g.resolution_m) {
            const double h = Cell(g, x, y);
            if (h <= -12) break;  // the foot of the face
            if (h < -2) s.push_back(y), z.push_back(h);
        }
        ASSERT_GT(s.size(), 20u) << x;
        const double slope_deg = std::atan(std::abs(FitSlope(s, z))) * 180 / kPi;
        EXPECT_GT(slope_deg, 60.0) << x;
        EXPECT_LT(slope_deg, 70.0) << x;
        if (slope_deg > 60) ++steep_profiles;
    }
    EXPECT_EQ(steep_profiles, 11);
    // The same face walked along the benches' side (south) is the benched profile: no face
    // between 2 and 12 m is steeper than 56 deg over its whole height there.
    std::vector<double> s, z;
    for (double y = -sc_->pit.half_width_m - 2; y < 0; y += g.resolution_m) {
        const double h = Cell(g, 12.0, y);
        if (h <= -12) break;
        if (h < -2) s.push_back(y), z.push_back(h);
    }
    EXPECT_LT(std::atan(std::abs(FitSlope(s, z))) * 180 / kPi, 50.0);
}

TEST_F(Quarry, HasARampFromTheShoreDownToTheFirstBench) {
    const auto ramp = PlanRamp(sc_->pit);
    ASSERT_TRUE(ramp.has_value());
    const TerrainGrid& g = world_->grid();
    const Eigen::Vector2d axis = (ramp->bottom - ramp->top).normalized();
    const Eigen::Vector2d across(-axis.y(), axis.x());
    // Along the centre line: a straight incline at the grade, from the water line.
    std::vector<double> s, z;
    for (double u = 1.0; u < ramp->length_m() - 1.0; u += 0.25) {
        const Eigen::Vector2d p = ramp->top + u * axis;
        s.push_back(u);
        z.push_back(Cell(g, p.x(), p.y()));
    }
    const double grade_deg = std::atan(-FitSlope(s, z)) * 180 / kPi;
    EXPECT_NEAR(grade_deg, sc_->pit.ramp_grade_deg, 1.0);
    EXPECT_GT(ramp->length_m(), 20.0);
    EXPECT_NEAR(Cell(g, ramp->top.x(), ramp->top.y()), 0.0, 0.5);  // starts at the shore
    const double bench_depth = sc_->pit.floor_depth_m / (sc_->pit.num_benches + 1);
    EXPECT_NEAR(Cell(g, ramp->bottom.x(), ramp->bottom.y()), -bench_depth, 0.5);
    // The bottom lies on the bench: flat ground a metre further along the tread.
    const Eigen::Vector2d beyond = ramp->bottom + 1.0 * axis;
    EXPECT_NEAR(Cell(g, beyond.x(), beyond.y()), -bench_depth, 0.5);
    // Across: a road, level over its width (rubble and the odd boulder on it), at a quarter,
    // half and three quarters of its length.
    for (double f : {0.25, 0.5, 0.75}) {
        const Eigen::Vector2d c = ramp->top + f * ramp->length_m() * axis;
        std::vector<double> v, h;
        for (double w = -0.4 * ramp->width_m; w <= 0.4 * ramp->width_m; w += 0.1) {
            const Eigen::Vector2d p = c + w * across;
            v.push_back(w);
            h.push_back(Cell(g, p.x(), p.y()));
        }
        EXPECT_LT(std::abs(FitSlope(v, h)), std::tan(8 * kPi / 180)) << f;
    }
    // And it is really there: without it the ground along the line differs by metres.
    PitConfig no_ramp = sc_->pit;
    no_ramp.ramp_width_m = 0;
    const PitWorld plain(no_ramp, sc_->seed);
    double most = 0;
    for (std::size_t i = 0; i < s.size(); ++i) {
        const Eigen::Vector2d p = ramp->top + s[i] * axis;
        most = std::max(most, std::abs(Cell(plain.grid(), p.x(), p.y()) - z[i]));
    }
    EXPECT_GT(most, 0.8);
}

TEST_F(Quarry, HasBouldersStandingOnGentleGround) {
    const auto& boulders = world_->boulders();
    ASSERT_EQ(static_cast<int>(boulders.size()), sc_->pit.num_boulders);
    const TerrainGrid& g = world_->grid();
    int prominent = 0;
    for (const Boulder& b : boulders) {
        EXPECT_GE(b.diameter_m, sc_->pit.boulder_min_diameter_m);
        EXPECT_LE(b.diameter_m, sc_->pit.boulder_max_diameter_m);
        // Measured on the truth grid: the centre stands above the median of a ring around it.
        std::vector<double> ring;
        const double r = 0.5 * b.diameter_m + 0.6;
        for (int k = 0; k < 32; ++k) {
            const double a = 2 * kPi * k / 32;
            ring.push_back(Cell(g, b.centre.x() + r * std::cos(a), b.centre.y() + r * std::sin(a)));
        }
        std::nth_element(ring.begin(), ring.begin() + 16, ring.end());
        const double prominence = Cell(g, b.centre.x(), b.centre.y()) - ring[16];
        EXPECT_GT(prominence, 0.5 * b.height_m) << b.centre.transpose();
        EXPECT_LT(Cell(g, b.centre.x(), b.centre.y()), -1.5);  // under water
        if (prominence > 0.25) ++prominent;
    }
    EXPECT_GE(prominent, 24);
    // Without boulders the grid differs only around them.
    PitConfig none = sc_->pit;
    none.num_boulders = 0;
    const PitWorld plain(none, sc_->seed);
    std::size_t changed = 0;
    for (std::size_t i = 0; i < g.height_m.size(); ++i)
        if (g.height_m[i] != plain.grid().height_m[i]) ++changed;
    double footprint = 0;
    for (const Boulder& b : boulders) footprint += b.diameter_m * b.diameter_m;
    EXPECT_GT(changed, 0u);
    EXPECT_LT(static_cast<double>(changed) * g.resolution_m * g.resolution_m, footprint);
}

TEST(Scenario, QuarryFeaturesAreValidated) {
    ScenarioConfig s = *BuiltinScenario("quarry");
    s.pit.high_wall_slope_deg = 95;
    s.pit.ramp_bench = 5;
    s.pit.boulder_max_diameter_m = 0.1;
    s.sonar.nmea_heading_rate_hz = 20;
    s.sonar.nmea_latency_s = -1;
    EXPECT_EQ(s.Validate().size(), 5u);
}

}  // namespace
}  // namespace pitmap::sim
