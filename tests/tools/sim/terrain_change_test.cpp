// SPDX-License-Identifier: MIT
// The repeat survey's changes (tools/sim/terrain_change.hpp): each part's volume from its
// formula against the volume summed over the terrain grid, the slump's mass balance, the
// outlines, the epoch's scenario and the capacity curve.
#include "tools/sim/terrain_change.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace pitmap::sim {
namespace {

constexpr double kPi = 3.14159265358979323846;

TerrainGrid FlatGrid(double z, double half, double res) {
    TerrainGrid g;
    g.resolution_m = res;
    g.x0_m = g.y0_m = -half;
    g.nx = g.ny = static_cast<int>(std::lround(2 * half / res)) + 1;
    g.height_m.assign(static_cast<std::size_t>(g.nx) * static_cast<std::size_t>(g.ny),
                      static_cast<float>(z));
    return g;
}

bool InsideRing(const std::vector<Eigen::Vector2d>& ring, double x, double y) {
    bool in = false;
    for (std::size_t i = 0, j = ring.size() - 1; i < ring.size(); j = i++) {
        const auto& a = ring[i];
        const auto& b = ring[j];
        if ((a.y() > y) != (b.y() > y) &&
            x < (b.x() - a.x()) * (y - a.y()) / (b.y() - a.y()) + a.x())
            in = !in;
    }
    return in;
}

ScenarioConfig Quarry2() {
    auto q = BuiltinScenario("quarry");
    EXPECT_TRUE(q.ok());
    auto r = RepeatEpoch(*q, 2);
    EXPECT_TRUE(r.ok());
    return *r;
}

TEST(TerrainChange, ShapesVolumeByFormulaMatchesTheGrid) {
    const TerrainGrid g = FlatGrid(-10, 12, 0.05);
    ChangePart para{"p", "c", ChangeShape::kParaboloid, 1.0, -2.0, 30.0, 4.0, 2.0, 0, 0.8};
    ChangePart heap{"f", "c", ChangeShape::kFrustum, -3.0, 2.0, 0.0, 1.5, 3.0, 0, 0.6};
    ChangePart box{"b", "c", ChangeShape::kBox, 4.0, 4.0, -25.0, 2.0, 1.5, 0.5, -0.35};
    EXPECT_NEAR(para.AnalyticVolume(), kPi * 4 * 2 * 0.8 / 2, 1e-12);
    EXPECT_NEAR(heap.AnalyticVolume(), kPi * 0.6 * (2.25 + 4.5 + 9) / 3, 1e-12);
    EXPECT_NEAR(box.AnalyticVolume(), -0.35 * 4.5 * 3.5, 1e-12);
    for (const ChangePart& p : {para, heap, box}) {
        EXPECT_TRUE(p.Validate().empty()) << p.name;
        EXPECT_NEAR(GridVolume(g, p), p.AnalyticVolume(), 0.002 * std::abs(p.AnalyticVolume()))
            << p.name;
    }
}

TEST(TerrainChange, QuarryChangesVolumesAgreeAndTheSlumpMovesMaterial) {
    const ScenarioConfig sc = Quarry2();
    ASSERT_EQ(sc.changes.size(), 5u);
    const PitWorld before(sc.pit, sc.TerrainSeed());
    double scar = 0, toe = 0;
    for (const ChangePart& p : sc.changes) {
        // The truth grid (0.1 m) against the formula: within 1 %.
        const double grid_v = GridVolume(before.grid(), p);
        EXPECT_NEAR(grid_v, p.AnalyticVolume(), 0.01 * std::abs(p.AnalyticVolume())) << p.name;
        // Changes of at least 4 m3 and 0.15 m thick (the smaller class).
        EXPECT_GE(std::abs(p.AnalyticVolume()), 4.0) << p.name;
        EXPECT_GE(std::abs(p.thickness_m), 0.15) << p.name;
        if (p.name == "slump_scar") scar = grid_v;
        if (p.name == "slump_toe") toe = grid_v;
    }
    EXPECT_LT(scar, -8.0);
    EXPECT_NEAR(toe, -scar, 0.01 * std::abs(scar));
}

TEST(TerrainChange, PartsLieUnderWaterApartAndTheScarOnTheWall) {
    const ScenarioConfig sc = Quarry2();
    const PitWorld before(sc.pit, sc.TerrainSeed());
    for (std::size_t i = 0; i < sc.changes.size(); ++i) {
        const ChangePart& p = sc.changes[i];
        for (const Eigen::Vector2d& q : p.Outline()) {
            EXPECT_LT(before.Height(q.x(), q.y()), -1.0) << p.name << " reaches the shore";
        }
        for (std::size_t k = i + 1; k < sc.changes.size(); ++k) {
            for (const Eigen::Vector2d& q : sc.changes[k].Outline()) {
                EXPECT_EQ(p.Profile(q.x(), q.y()), 0.0)
                    << p.name << " overlaps " << sc.changes[k].name;
            }
        }
        const double slope_deg = std::atan(before.Gradient(p.x_m, p.y_m).norm()) * 180.0 / kPi;
        if (p.name == "slump_scar") {
            EXPECT_GT(slope_deg, 55.0);
        } else {
            EXPECT_LT(slope_deg, 40.0) << p.name;
        }
    }
}

// Every scenario's parts lie 1 m apart, the floor's on the floor: a survey measures the net
// change, so where two parts overlap neither's volume can be measured alone. Scaled from the
// quarry's layout, bejanca's slump toe ran 0.5 m into the cut's side before the parts were
// kept apart (6.4 m^2 where +0.36 and -1.24 m^3 netted out).
TEST(TerrainChange, EveryScenariosPartsLieApartAndOnTheFloor) {
    for (const std::string& name : BuiltinScenarioNames()) {
        auto first = BuiltinScenario(name);
        ASSERT_TRUE(first.ok()) << name;
        auto sc = RepeatEpoch(*first, 2);
        ASSERT_TRUE(sc.ok()) << name;
        const PitWorld before(sc->pit, sc->TerrainSeed());
        ASSERT_EQ(sc->changes.size(), 5u) << name;
        for (std::size_t i = 0; i < sc->changes.size(); ++i) {
            const ChangePart& p = sc->changes[i];
            for (std::size_t k = i + 1; k < sc->changes.size(); ++k) {
                // The slump's scar and toe are one change: they touch, but do not overlap.
                const double gap = p.change == sc->changes[k].change ? 0.0 : 0.9;
                EXPECT_TRUE(PartsApart(p, sc->changes[k], gap))
                    << name << ": " << p.name << " within " << gap << " m of "
                    << sc->changes[k].name;
            }
            if (p.change == "slump") continue;
            for (const Eigen::Vector2d& q : p.Outline()) {
                EXPECT_LT(before.Height(q.x(), q.y()), -1.0) << name << ": " << p.name;
            }
            const double slope_deg = std::atan(before.Gradient(p.x_m, p.y_m).norm()) * 180.0 / kPi;
            EXPECT_LT(slope_deg, 40.0) << name << ": " << p.name;
        }
    }
}

TEST(TerrainChange, OutlineHoldsEveryChangedNode) {
    const ScenarioConfig sc = Quarry2();
    const PitWorld before(sc.pit, sc.TerrainSeed());
    const TerrainGrid& g = before.grid();
    for (const ChangePart& p : sc.changes) {
        const std::vector<Eigen::Vector2d> ring = p.Outline();
        const std::vector<float> d = ChangeGrid(g, {p});
        int changed = 0;
        for (int j = 0; j < g.ny; ++j) {
            for (int i = 0; i < g.nx; ++i) {
                if (d[static_cast<std::size_t>(j) * g.nx + i] == 0.0f) continue;
                ++changed;
                EXPECT_TRUE(
                    InsideRing(ring, g.x0_m + i * g.resolution_m, g.y0_m + j * g.resolution_m))
                    << p.name;
            }
        }
        EXPECT_GT(changed, 100) << p.name;
    }
}

TEST(TerrainChange, EpochTwoIsTheSamePitChangedAndSurveyedAnew) {
    auto first = BuiltinScenario("quarry");
    ASSERT_TRUE(first.ok());
    const ScenarioConfig one = *RepeatEpoch(*first, 1);
    EXPECT_TRUE(one.changes.empty());
    EXPECT_EQ(one.seed, first->seed);
    const ScenarioConfig two = Quarry2();
    EXPECT_TRUE(two.Validate().empty());
    EXPECT_EQ(two.epoch, 2);
    EXPECT_EQ(two.TerrainSeed(), first->seed);
    EXPECT_NE(two.seed, first->seed);
    EXPECT_EQ(two.start_utc, "2026-09-14T09:00:00Z");
    EXPECT_TRUE(two.track.clockwise);
    EXPECT_NE(two.boresight_deg, first->boresight_deg);
    EXPECT_NE(two.sonar.topside_clock_offset_s, first->sonar.topside_clock_offset_s);
    EXPECT_FALSE(RepeatEpoch(*first, 0).ok());
    EXPECT_FALSE(RepeatEpoch(*first, 10).ok());
    // The terrain: epoch 1's plus the change grid, and nothing else.
    const PitWorld w1 = MakeWorld(one);
    const PitWorld w2 = MakeWorld(two);
    const std::vector<float> delta = ChangeGrid(w1.grid(), two.changes);
    ASSERT_EQ(w1.grid().height_m.size(), w2.grid().height_m.size());
    std::size_t same = 0;
    for (std::size_t i = 0; i < delta.size(); ++i) {
        EXPECT_NEAR(w2.grid().height_m[i] - w1.grid().height_m[i], delta[i], 1e-5);
        same += delta[i] == 0.0f;
    }
    // Large stable areas: over 95 % of the grid.
    EXPECT_GT(static_cast<double>(same) / static_cast<double>(delta.size()), 0.95);
}

TEST(TerrainChange, CapacityCurveOfABoxBasin) {
    // A flat floor at -2 m with a 0.5 m deep box cut: volume below level L is the floor's
    // (L + 2) * area plus the cut's volume once the floor is covered.
    TerrainGrid g = FlatGrid(-2.0, 5, 0.05);
    const ChangePart cut{"c", "c", ChangeShape::kBox, 0, 0, 0, 1.0, 1.0, 0.4, -0.5};
    const std::vector<float> d = ChangeGrid(g, {cut});
    for (std::size_t i = 0; i < d.size(); ++i) g.height_m[i] += d[i];
    const double area = 10.05 * 10.05;  // nodes x cell area
    const auto curve = CapacityCurve(g, -1.0, 0.0, 0.5);
    ASSERT_EQ(curve.size(), 3u);
    for (const CapacityPoint& c : curve) {
        EXPECT_NEAR(c.area_m2, area, 1e-6);
        EXPECT_NEAR(c.volume_m3, (c.level_m + 2.0) * area - cut.AnalyticVolume(), 0.01);
    }
}

}  // namespace
}  // namespace pitmap::sim
