// SPDX-License-Identifier: MIT
#include "tools/sim/sonar_model.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <map>

#include "common/frames.hpp"

namespace pitmap::sim {
namespace {

TerrainGrid FlatGrid(double z) {
    TerrainGrid g;
    g.resolution_m = 0.5;
    g.x0_m = g.y0_m = -100;
    g.nx = g.ny = 401;
    g.height_m.assign(static_cast<std::size_t>(g.nx * g.ny), static_cast<float>(z));
    return g;
}

// Sonar 0.25 m below the surface, level, looking down.
Pose LevelSonar() {
    return MakePose(frames::RotationWorldFromRpy(0, 0, 0), Eigen::Vector3d(0, 0, -0.25));
}

TEST(SonarModel, GeometryOnAFlatFloorWithoutNoise) {
    const PitWorld world(FlatGrid(-10.25));
    SonarConfig cfg;
    cfg.range_noise_fraction = 0;
    cfg.range_noise_constant_m = 0;
    cfg.dropout_probability = 0;
    cfg.outlier_probability = 0;
    cfg.footprint_rays = 1;
    SonarModel sonar(cfg, world, 1);
    const SimPing p = sonar.Ping(LevelSonar(), 0);
    ASSERT_EQ(p.range_counts.size(), 480u);
    EXPECT_DOUBLE_EQ(sonar.BeamAngleDeg(0), -60.0);
    EXPECT_DOUBLE_EQ(sonar.BeamAngleDeg(240), 0.0);
    EXPECT_DOUBLE_EQ(sonar.BeamAngleDeg(479), 59.75);
    for (int i : {0, 100, 240, 400, 479}) {
        const double expected = 10.0 / std::cos(frames::DegToRad(sonar.BeamAngleDeg(i)));
        EXPECT_NEAR(p.true_range_m[static_cast<std::size_t>(i)], expected, 1e-3) << i;
        EXPECT_NEAR(p.range_counts[static_cast<std::size_t>(i)] * 0.005, expected, 0.0026) << i;
        EXPECT_EQ(p.outcome[static_cast<std::size_t>(i)], BeamOutcome::kValid);
    }
}

TEST(SonarModel, NoiseDropoutsAndOutliersHaveTheConfiguredRates) {
    const PitWorld world(FlatGrid(-20.25));
    SonarConfig cfg;  // defaults: 0.2 % + 2 cm, 2 % dropouts, 2 % outliers
    SonarModel sonar(cfg, world, 9);
    double sum = 0, sum2 = 0;
    int valid = 0, dropouts = 0, outliers = 0, total = 0;
    for (int ping = 0; ping < 200; ++ping) {
        const SimPing p = sonar.Ping(LevelSonar(), ping);
        for (std::size_t i = 200; i < 280; ++i) {  // near nadir: range about 20 m
            ++total;
            if (p.outcome[i] == BeamOutcome::kDropout) {
                ++dropouts;
                EXPECT_EQ(p.range_counts[i], 0);
            } else if (p.outcome[i] == BeamOutcome::kOutlier) {
                ++outliers;
            } else {
                const double err = p.range_counts[i] * 0.005 - p.true_range_m[i];
                sum += err;
                sum2 += err * err;
                ++valid;
            }
        }
    }
    const double sigma = std::sqrt(sum2 / valid - (sum / valid) * (sum / valid));
    EXPECT_NEAR(sigma, sonar.RangeSigma(20.1), 0.1 * sonar.RangeSigma(20.1));
    EXPECT_NEAR(sum / valid, 0.0, 0.003);
    EXPECT_NEAR(static_cast<double>(dropouts) / total, 0.02, 0.006);
    EXPECT_NEAR(static_cast<double>(outliers) / total, 0.02, 0.006);
}

TEST(SonarModel, SamePingNumberSameResultWhateverTheOrder) {
    const PitWorld world(FlatGrid(-15.0));
    SonarModel sonar(SonarConfig{}, world, 3);
    const SimPing a = sonar.Ping(LevelSonar(), 17);
    (void)sonar.Ping(LevelSonar(), 18);
    const SimPing b = sonar.Ping(LevelSonar(), 17);
    EXPECT_EQ(a.range_counts, b.range_counts);
    EXPECT_EQ(a.intensities, b.intensities);
    EXPECT_NE(a.range_counts, sonar.Ping(LevelSonar(), 19).range_counts);
}

TEST(SonarModel, BeamsPastTheShoreOrOutOfRangeReportNothing) {
    const PitWorld world(FlatGrid(-150.0));  // deeper than the 100 m range
    SonarModel sonar(SonarConfig{}, world, 3);
    const SimPing p = sonar.Ping(LevelSonar(), 0);
    for (std::size_t i = 0; i < p.range_counts.size(); ++i) {
        EXPECT_EQ(p.range_counts[i], 0);
        EXPECT_EQ(p.outcome[i], BeamOutcome::kNoHit);
    }
}

// The intensities follow BackscatterConfig's sonar equation: without speckle, every beam's
// 20 log10(intensity) is the level the model states, within the amplitude's rounding.
TEST(SonarModel, IntensitiesFollowTheSonarEquation) {
    const PitWorld world(FlatGrid(-10.25));
    SonarConfig cfg;
    cfg.range_noise_fraction = 0;
    cfg.range_noise_constant_m = 0;
    cfg.dropout_probability = 0;
    cfg.outlier_probability = 0;
    cfg.footprint_rays = 1;
    BackscatterConfig bs;
    bs.speckle_db = 0;
    bs.patch_levels_db = {-20.0};  // one material everywhere
    SonarModel sonar(cfg, world, 1, nullptr, bs);
    const SeabedBackscatter seabed(bs, 1);
    const SimPing p = sonar.Ping(LevelSonar(), 0);
    for (int i : {0, 60, 200, 240, 300, 479}) {
        const auto k = static_cast<std::size_t>(i);
        const double theta = std::abs(sonar.BeamAngleDeg(i));
        const double r = 10.0 / std::cos(frames::DegToRad(theta));
        const double want = bs.source_level_db - 40 * std::log10(r) - 2 * 0.021 * r - 20.0 +
                            20 * std::log10(std::cos(frames::DegToRad(theta))) +
                            6.0 * std::exp(-std::pow(theta / 10.0, 2));
        EXPECT_NEAR(seabed.LevelDb(r, theta, -20.0), want, 1e-9);
        // Rounding the amplitude: at most half a count.
        EXPECT_NEAR(
            p.intensities[k], std::pow(10.0, want / 20), 0.5 + 1e-3 * std::pow(10.0, want / 20))
            << i;
    }
    // The specular lobe: nadir is brighter than Lambert's law says, by specular_db.
    EXPECT_NEAR(seabed.AngularResponseDb(0.0), 6.0, 1e-12);
    EXPECT_NEAR(seabed.AngularResponseDb(60.0), 20 * std::log10(0.5), 1e-6);
}

TEST(SeabedBackscatter, PatchesAreSquaresOfTheLevelsAndBouldersAreHarder) {
    BackscatterConfig c;
    const SeabedBackscatter a(c, 5, {Boulder{Eigen::Vector2d(12.0, 3.0), 2.0, 0.8}});
    // Constant inside a square, every level used, deterministic in the seed.
    std::map<double, int> seen;
    for (int ix = -10; ix < 10; ++ix) {
        for (int iy = -10; iy < 10; ++iy) {
            const double x = ix * c.patch_size_m, y = iy * c.patch_size_m;
            if (std::hypot(x + 2.5 - 12.0, y + 2.5 - 3.0) < 5) continue;  // the boulder's square
            const double v = a.At(x + 0.1, y + 0.1);
            EXPECT_EQ(a.At(x + c.patch_size_m - 0.1, y + c.patch_size_m - 0.1), v);
            ++seen[v];
        }
    }
    EXPECT_EQ(seen.size(), c.patch_levels_db.size());
    for (const auto& [v, n] : seen) EXPECT_GT(n, 50) << v;  // 400 squares, 4 levels
    EXPECT_EQ(a.At(12.3, 3.4), c.boulder_db);
    EXPECT_NE(a.At(14.5, 3.0), c.boulder_db);
    const SeabedBackscatter b(c, 6);
    int differ = 0;
    for (int k = 0; k < 50; ++k)
        differ += a.PatchIndex(k * 5.0 + 1, 1) != b.PatchIndex(k * 5.0 + 1, 1);
    EXPECT_GT(differ, 20);
}

}  // namespace
}  // namespace pitmap::sim
