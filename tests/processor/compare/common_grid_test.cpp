// SPDX-License-Identifier: MIT
// Two surveys gridded at different resolutions (processor/compare/common_grid.hpp, decision
// 030): the coarser one gridded again from its soundings at the finer resolution, so that the
// DEM of difference of unchanged benches flags no change along their crests and risers.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "processor/compare/change.hpp"
#include "processor/compare/common_grid.hpp"
#include "processor/hydro/cube.hpp"

namespace pitmap::proc::compare {
namespace {

constexpr double kPi = 3.14159265358979323846;

// Benches of a pit wall: 4 m treads and 1.5 m risers at 65 deg, the crests and feet sharp
// (as blasted benches are), running at 20 deg to the grid's columns; a gentle swell along them.
double BenchHeight(double x, double y) {
    const double c = std::cos(20.0 * kPi / 180.0), s = std::sin(20.0 * kPi / 180.0);
    const double u = c * x + s * y, v = -s * x + c * y;
    const double riser = 1.5, run = riser / std::tan(65.0 * kPi / 180.0), tread = 4.0;
    const double period = tread + run;
    const double k = std::floor(u / period);
    const double w = u - k * period;
    const double step = w < tread ? 0.0 : (w - tread) / run * riser;
    return -(k * riser + step) + 0.1 * std::sin(v / 3.0);
}

// One survey of the benches: soundings at random places with their vertical and horizontal
// errors and a pass-common part shared by all the soundings of a 20 s pass.
std::vector<hydro::CubeSounding> Survey(unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> ux(0.0, 16.0), uy(0.0, 12.0);
    std::normal_distribution<double> nv(0.0, 0.025), nh(0.0, 0.015), npass(0.0, 0.008);
    std::vector<hydro::CubeSounding> out;
    const int passes = 6;
    const int per_pass = 16 * 12 * 450 / passes;
    for (int p = 0; p < passes; ++p) {
        const double pass_dz = npass(rng);
        for (int k = 0; k < per_pass; ++k) {
            const double x = ux(rng), y = uy(rng);
            hydro::CubeSounding s;
            s.x = x;
            s.y = y;
            // Where the beam really hit: off by the horizontal error.
            s.z = BenchHeight(x + nh(rng), y + nh(rng)) + nv(rng) + pass_dz;
            s.sigma_v_m = 0.03f;
            s.sigma_h_m = 0.018f;
            s.depth_m = 8.0f;
            s.sigma_common_m = 0.01f;
            s.sigma_h_common_m = 0.005f;
            s.time_s = static_cast<float>(60.0 * p + 20.0 * k / per_pass);
            out.push_back(s);
        }
    }
    return out;
}

SurfaceGrid Gridded(const std::vector<hydro::CubeSounding>& soundings, double resolution_m) {
    hydro::CubeConfig cfg;
    cfg.resolution_m = resolution_m;
    cfg.num_threads = 1;
    const hydro::CubeResult r = hydro::RunCube(soundings, cfg);
    EXPECT_TRUE(r.ok) << r.message;
    SurfaceGrid g;
    g.x0 = r.grid.x0;
    g.y0 = r.grid.y0;
    g.resolution_m = r.grid.resolution_m;
    g.nx = r.grid.nx;
    g.ny = r.grid.ny;
    g.z_m = r.grid.elevation_m;
    g.sigma_m = r.grid.uncertainty_m;
    for (float& v : g.sigma_m) v /= 1.96f;  // as dem.tif's 95 % band is read
    return g;
}

// The share of the compared nodes that lie in a change region (nothing changed: all false).
double FlaggedShare(const SurfaceGrid& a, const SurfaceGrid& b) {
    const ChangeResult r =
        ComputeChange(a, b, RigidCorrection{}, Eigen::Matrix<double, 6, 6>::Zero(), {});
    EXPECT_GT(r.compared_nodes, 10000u);
    return r.significant_share;
}

TEST(CompareCommonGrid, PlanGridsTheCoarserSurveyAgainAtTheFinerResolution) {
    EXPECT_EQ(PlanCommonGrid(0.1, 0.2).regrid, Regridded::kB);
    EXPECT_DOUBLE_EQ(PlanCommonGrid(0.1, 0.2).resolution_m, 0.1);
    EXPECT_EQ(PlanCommonGrid(0.25, 0.1).regrid, Regridded::kA);
    EXPECT_DOUBLE_EQ(PlanCommonGrid(0.25, 0.1).resolution_m, 0.1);
    EXPECT_EQ(PlanCommonGrid(0.2, 0.2).regrid, Regridded::kNone);
}

TEST(CompareCommonGrid, UnchangedBenchesGriddedAtTwoResolutionsFlagNoChangeOnACommonGrid) {
    const std::vector<hydro::CubeSounding> sa = Survey(11), sb = Survey(12);
    const SurfaceGrid a = Gridded(sa, 0.1);  // A's survey picked 0.1 m
    const SurfaceGrid b = Gridded(sb, 0.2);  // B's, deeper on average, 0.2 m
    // As the surveys come: B's coarser surface interpolated on A's nodes reads the crests and
    // the risers' feet, which its 0.3 m capture distance rounds, as change; filtering A by
    // the tent of B's spacing (what bilinear interpolation does to B) does not make the two
    // CUBE surfaces alike.
    const double mixed = FlaggedShare(a, b);
    const double filtered = FlaggedShare(TentFiltered(a, 2), b);
    EXPECT_GT(mixed, 0.003);
    EXPECT_GT(filtered, 0.003);
    int regrids = 0;
    const RegridSurvey regrid_b = [&](double res) -> Expected<SurfaceGrid> {
        ++regrids;
        return Gridded(sb, res);
    };
    const RegridSurvey not_a = [](double) -> Expected<SurfaceGrid> {
        ADD_FAILURE() << "A is the finer survey: it is not gridded again";
        return Error{"not A"};
    };
    auto common = OnCommonGrid(a, b, not_a, regrid_b);
    ASSERT_TRUE(common) << common.error().message;
    EXPECT_EQ(regrids, 1);
    EXPECT_EQ(common->plan.regrid, Regridded::kB);
    EXPECT_DOUBLE_EQ(common->b.resolution_m, 0.1);
    // A as it was, node for node (NaN where empty).
    ASSERT_EQ(common->a.z_m.size(), a.z_m.size());
    for (std::size_t k = 0; k < a.z_m.size(); ++k) {
        ASSERT_TRUE(common->a.z_m[k] == a.z_m[k] ||
                    (std::isnan(common->a.z_m[k]) && std::isnan(a.z_m[k])));
    }
    // The bound for stable terrain, walls included: under 0.3 % flagged.
    const double one_grid = FlaggedShare(common->a, common->b);
    EXPECT_LT(one_grid, 0.003) << "mixed " << mixed << ", A filtered " << filtered;
    std::printf(
        "stable share flagged: B at 0.2 m on A's grid %.3f %%, A tent-filtered %.3f %%, "
        "B gridded again at 0.1 m %.3f %%\n",
        100 * mixed,
        100 * filtered,
        100 * one_grid);
}

TEST(CompareCommonGrid, ARegridThatFailsOrComesBackWrongIsAnError) {
    SurfaceGrid a, b;
    a.resolution_m = 0.1;
    b.resolution_m = 0.2;
    a.nx = a.ny = b.nx = b.ny = 2;
    a.z_m = b.z_m = a.sigma_m = b.sigma_m = std::vector<float>(4, 1.0f);
    const RegridSurvey fails = [](double) -> Expected<SurfaceGrid> {
        return Error{"B (P2): survey.pitmap damaged"};
    };
    auto r = OnCommonGrid(a, b, nullptr, fails);
    ASSERT_FALSE(r);
    EXPECT_NE(r.error().message.find("survey.pitmap damaged"), std::string::npos);
    const RegridSurvey wrong = [&](double) -> Expected<SurfaceGrid> { return b; };
    r = OnCommonGrid(a, b, nullptr, wrong);
    ASSERT_FALSE(r);
    EXPECT_NE(r.error().message.find("0.200 m, not the 0.100 m"), std::string::npos);
    const RegridSurvey empty = [&](double res) -> Expected<SurfaceGrid> {
        SurfaceGrid e = b;
        e.resolution_m = res;
        e.z_m.assign(4, std::nanf(""));
        return e;
    };
    r = OnCommonGrid(a, b, nullptr, empty);
    ASSERT_FALSE(r);
    EXPECT_NE(r.error().message.find("no heights"), std::string::npos);
    // Equal resolutions: neither is gridded again.
    b.resolution_m = 0.1;
    auto same = OnCommonGrid(a, b, nullptr, nullptr);
    ASSERT_TRUE(same);
    EXPECT_EQ(same->plan.regrid, Regridded::kNone);
}

}  // namespace
}  // namespace pitmap::proc::compare
