// SPDX-License-Identifier: MIT
// The sound speed uncertainty from the data (processor/hydro/sound_speed.hpp): the cast's
// growth terms, the a-priori bound, the refraction-error relation of the TPU against exact ray
// tracing, and the swath-overlap estimate on synthetic soundings with a known column error.
#include "processor/hydro/sound_speed.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>

#include "common/frames.hpp"
#include "processor/hydro/tpu.hpp"
#include "processor/svp/ray_trace.hpp"
#include "processor/svp/seawater.hpp"

namespace pitmap::proc::hydro {
namespace {

TEST(SoundSpeedSigma, CastSigmaGrowsWithAgeDistanceAndTheSurfaceDisagreement) {
    SoundSpeedSigmaConfig cfg;
    cfg.cast_age_rate_mps_per_h = 1.0;
    cfg.cast_distance_rate_mps_per_km = 2.0;
    const double nan = std::nan("");
    EXPECT_DOUBLE_EQ(CastSpeedSigma(0.5, nan, nan, nan, cfg), 0.5);
    EXPECT_DOUBLE_EQ(CastSpeedSigma(0.5, 0, 0, 0, cfg), 0.5);
    // Two hours before or after the cast: 2 m/s in quadrature.
    EXPECT_NEAR(CastSpeedSigma(0.5, 7200, nan, nan, cfg), std::hypot(0.5, 2.0), 1e-12);
    EXPECT_NEAR(CastSpeedSigma(0.5, -7200, nan, nan, cfg), std::hypot(0.5, 2.0), 1e-12);
    // 1.5 km away: 3 m/s; a surface 4 m/s off the cast: 4 m/s.
    EXPECT_NEAR(CastSpeedSigma(0.5, nan, 1500, nan, cfg), std::hypot(0.5, 3.0), 1e-12);
    EXPECT_NEAR(CastSpeedSigma(0.5, nan, nan, -4.0, cfg), std::hypot(0.5, 4.0), 1e-12);
    EXPECT_NEAR(CastSpeedSigma(0, 3600, 500, 2, cfg), std::sqrt(1.0 + 1.0 + 4.0), 1e-12);
    cfg.cast_age_rate_mps_per_h = -1;
    EXPECT_FALSE(cfg.Validate().empty());
    EXPECT_TRUE(SoundSpeedSigmaConfig{}.Validate().empty());
    SoundSpeedSigmaConfig edges;
    edges.overlap_depth_edges_m = {5, 3};
    EXPECT_FALSE(edges.Validate().empty());
}

TEST(SoundSpeedSigma, NoCastBoundIsTheRangeToWaterAtFourDegrees) {
    // Fresh water at 4 degC, surface pressure (Chen & Millero): 1421.6 m/s.
    const double c4 = svp::SoundSpeedChenMillero(0, 4, 0);
    EXPECT_NEAR(c4, 1421.6, 0.3);
    EXPECT_NEAR(NoCastPriorSigma(1496.0), (1496.0 - c4) / std::sqrt(3.0), 1e-9);
    EXPECT_NEAR(NoCastPriorSigma(c4), 0.0, 1e-9);
    EXPECT_NEAR(NoCastPriorSigma(1410.0), (c4 - 1410.0) / std::sqrt(3.0), 1e-9);  // ice-covered
}

TEST(SoundSpeedSigma, RegressorIsTheDepthTimesOneMinusTanSquared) {
    EXPECT_NEAR(RefractionRegressor(Eigen::Vector3d(0, 0, -10)), 10.0, 1e-12);
    EXPECT_NEAR(RefractionRegressor(Eigen::Vector3d(10, 0, -10)), 0.0, 1e-12);  // 45 deg
    const double t60 = std::tan(frames::DegToRad(60));
    EXPECT_NEAR(RefractionRegressor(Eigen::Vector3d(0, 10 * t60, -10)), -20.0, 1e-9);
    EXPECT_EQ(RefractionRegressor(Eigen::Vector3d(3, 0, 1)), 0.0);  // above the transducer
}

// The TPU's column term against exact ray tracing: a sounding computed with a profile of speed
// c0 when the water below the face runs at c0 + dc moves by what the closed-form tracer says;
// the TPU's 1-sigma for a column sigma of dc matches that displacement to first order.
TEST(SoundSpeedSigma, TpuColumnTermMatchesRayTracingOfAColumnSpeedError) {
    const double c0 = 1480.0, dc = 2.0, z0 = 0.5;
    const svp::LayeredProfile assumed({0.0, 100.0}, {c0, c0});
    const svp::LayeredProfile actual({0.0, 0.5, 0.5001, 100.0}, {c0, c0, c0 + dc, c0 + dc});
    TpuConfig cfg;
    cfg.sound_speed_mps = c0;
    cfg.model = SensorErrorModel{};
    cfg.model.range_sigma_m = cfg.model.range_sigma_fraction = 0;
    cfg.model.beam_angle_sigma_deg = cfg.model.surface_sound_speed_sigma_mps = 0;
    cfg.model.position_noise_m = cfg.model.lever_arm_sigma_m = cfg.model.boresight_sigma_deg = 0;
    cfg.model.latency_sigma_s = 0;
    cfg.column_swath_half_angle_deg = 0;  // the per-angle relation alone (the swath part below)
    PingSigma sig;
    sig.column_speed_sigma_mps = dc;
    for (const double deg : {0.0, 20.0, 35.0, 50.0, 60.0}) {
        const double th = frames::DegToRad(deg);
        const double t = 25.0 / std::cos(th) / c0;  // 25 m deep at the assumed speed
        const svp::RayEnd a = svp::TraceRay(assumed, z0, th, t, c0);
        const svp::RayEnd b = svp::TraceRay(actual, z0, th, t, c0);
        ASSERT_EQ(a.status, svp::RayStatus::kOk);
        ASSERT_EQ(b.status, svp::RayStatus::kOk);
        // The true point minus the computed one: the error of the sounding is its negative.
        const double dz = b.depth_m - a.depth_m, dx = b.horizontal_m - a.horizontal_m;
        SoundingGeometry g;  // level vehicle, beam in the y-z plane, 25 m deep at c0
        g.R_world_vehicle = frames::RotationWorldFromRpy(0, 0, 0);
        g.range_m = c0 * t;
        g.angle_rad = th;
        std::array<Eigen::Matrix3d, kNumTpuTerms> terms;
        (void)SoundingCovariance(g, sig, cfg, &terms);
        const Eigen::Matrix3d& C = terms[static_cast<int>(TpuTerm::kSoundSpeed)];
        // First order in dc / c (1.4e-3): agree within 2 % of the displacement (+ 0.1 mm).
        EXPECT_NEAR(std::sqrt(C(2, 2)), std::abs(dz), 0.02 * std::abs(dz) + 1e-4) << deg;
        EXPECT_NEAR(std::sqrt(C(0, 0) + C(1, 1)), std::abs(dx), 0.02 * std::abs(dx) + 1e-4) << deg;
    }
}

// The swath-common part of the column term (TpuConfig::column_swath_half_angle_deg): at 45 deg,
// where the per-angle relation's depth effect vanishes, the vertical sigma is the column error's
// effect averaged over a 0-60 deg fan, m d dc / c with m = (2 a - tan a) / a = 0.346; at nadir
// it joins the per-angle part d dc / c in quadrature; off, the 45 deg beam states none.
TEST(SoundSpeedSigma, SwathCommonPartOfTheColumnTermStaysAtFortyFiveDegrees) {
    const double c0 = 1480.0, dc = 20.0, depth = 15.0;
    TpuConfig cfg;
    cfg.sound_speed_mps = c0;
    cfg.model = SensorErrorModel{};
    cfg.model.surface_sound_speed_sigma_mps = 0;
    PingSigma sig;
    sig.column_speed_sigma_mps = dc;
    const auto vertical = [&](double deg, double half_angle_deg) {
        cfg.column_swath_half_angle_deg = half_angle_deg;
        SoundingGeometry g;
        g.R_world_vehicle = frames::RotationWorldFromRpy(0, 0, 0);
        g.angle_rad = frames::DegToRad(deg);
        g.range_m = depth / std::cos(g.angle_rad);
        std::array<Eigen::Matrix3d, kNumTpuTerms> terms;
        (void)SoundingCovariance(g, sig, cfg, &terms);
        return std::sqrt(terms[static_cast<int>(TpuTerm::kSoundSpeed)](2, 2));
    };
    const double a = frames::DegToRad(60.0);
    const double m = (2 * a - std::tan(a)) / a;
    EXPECT_NEAR(m, 0.346, 0.001);
    EXPECT_NEAR(vertical(45.0, 60.0), m * depth * dc / c0, 1e-4);
    EXPECT_NEAR(vertical(45.0, 0.0), 0.0, 1e-4);
    EXPECT_NEAR(vertical(0.0, 60.0), std::hypot(1.0, m) * depth * dc / c0, 1e-4);
    cfg.column_swath_half_angle_deg = 80;
    EXPECT_FALSE(cfg.Validate().empty());
}

// Soundings of a flat floor at 12 m from passes whose beams overlap, with a column speed error
// dc applied by the refraction-error relation and range noise: the overlap fit finds dc / c in
// the floor's depth class, with a standard error that covers it, and nothing where no
// soundings are. Without the error it finds nothing significant.
TEST(SoundSpeedSigma, OverlapFindsAKnownColumnSpeedError) {
    for (const double dc : {-20.0, 0.0, 3.0}) {
        const double c = 1500.0, depth = 12.0;
        std::mt19937_64 rng(11);
        std::normal_distribution<double> noise(0.0, 0.03);
        std::vector<Eigen::Vector3d> points, offsets;
        // Passes along y every 6 m, beams +-60 deg across: every spot seen at several angles.
        for (int pass = 0; pass < 8; ++pass) {
            const double x0 = 6.0 * pass;
            for (double y = 0; y < 40; y += 0.25) {
                for (double deg = -60; deg <= 60; deg += 1.0) {
                    const Eigen::Vector3d o(depth * std::tan(frames::DegToRad(deg)), 0, -depth);
                    const double dz = RefractionRegressor(o) * dc / c;
                    const Eigen::Vector3d p(x0 + o.x(), y, -depth + dz + noise(rng));
                    points.push_back(p);
                    offsets.push_back(o);
                }
            }
        }
        SoundSpeedSigmaConfig cfg;
        const OverlapSpeedEstimate e = EstimateColumnSpeedError(points, offsets, cfg);
        ASSERT_TRUE(e.estimated()) << e.message;
        const auto& k = e.classes[1];  // 10-15 m
        ASSERT_TRUE(k.estimated);
        EXPECT_NEAR(k.relative_error * c, dc, 0.3) << e.message;
        EXPECT_LT(k.relative_error_se * c, 0.3);
        EXPECT_FALSE(e.classes[0].estimated);  // 6-10 m: no soundings
        // The sigma at any depth: this class's (the only one estimated), with the prior.
        const double p = 1.0 / c;
        EXPECT_NEAR(e.RelativeSigmaAt(4.0, p),
                    ColumnRelativeSigma(p, k.relative_error, k.relative_error_se),
                    1e-15);
        EXPECT_EQ(e.StratifiedClass(c, cfg.overlap_stratified_mps), dc == -20.0 ? 1 : -1);
    }
    // No soundings: nothing estimated.
    const OverlapSpeedEstimate none = EstimateColumnSpeedError({}, {}, SoundSpeedSigmaConfig{});
    EXPECT_FALSE(none.estimated());
    EXPECT_TRUE(std::isnan(none.RelativeSigmaAt(10, 1.0 / 1500)));
}

// The overlap's estimate updates the column's prior (ColumnRelativeSigma, docs/decisions/028):
// a class the overlap hardly measures leaves the prior, one it measures well states what it
// measured, and one that contradicts the prior states the estimate on top of it.
TEST(SoundSpeedSigma, OverlapEstimateUpdatesThePriorColumnSigma) {
    const double p = 1.0 / 1500;  // the error model's 1 m/s
    // A 120 s quarry's 6-10 m class, homogeneous water: -0.069 +- 0.046 (1.5 se, 104 m/s).
    EXPECT_LT(ColumnRelativeSigma(p, -0.069, 0.046), 1.01 * p);
    EXPECT_GT(ColumnRelativeSigma(p, -0.069, 0.046), 0.99 * p);
    // Measured well and consistent with the prior: the measurement (0.2 +- 0.1 m/s).
    const double e = 0.2 / 1500, se = 0.1 / 1500;
    const double k = p * p / (p * p + se * se);
    EXPECT_NEAR(ColumnRelativeSigma(p, e, se), std::sqrt(k * k * e * e + k * se * se), 1e-15);
    EXPECT_LT(ColumnRelativeSigma(p, e, se), std::hypot(e, se));
    // Contradicting the prior (beyond 3 se): the estimate and the prior together.
    EXPECT_NEAR(ColumnRelativeSigma(p, -0.01, 0.001), std::sqrt(p * p + 1e-4 + 1e-6), 1e-15);
    // No prior (a column the error model states exact) and no contradiction: nothing.
    EXPECT_EQ(ColumnRelativeSigma(0.0, -0.069, 0.046), 0.0);
}

// The TPU with that class: a nadir sounding 4 or 8 m below the transducer states the TVU of the
// error model's column (1 m/s), not the 0.7 m (1 sigma at 8 m) that the flat prior made of
// -0.069 +- 0.046.
TEST(SoundSpeedSigma, TpuKeepsThePriorWhereTheOverlapMeasuresLittle) {
    const double c0 = 1500.0;
    auto est = std::make_shared<OverlapSpeedEstimate>();
    OverlapDepthClass shallow;
    shallow.lo_m = 6;
    shallow.hi_m = 10;
    shallow.estimated = true;
    shallow.relative_error = -0.069;
    shallow.relative_error_se = 0.046;
    OverlapDepthClass deep = shallow;
    deep.lo_m = 10;
    deep.hi_m = 15;
    deep.relative_error = 8e-6;
    deep.relative_error_se = 6e-5;
    est->classes = {shallow, deep};
    TpuConfig cfg;
    cfg.sound_speed_mps = c0;
    cfg.model = SensorErrorModel{};
    PingSigma sig;
    sig.column_speed_sigma_mps = 1.0;
    const auto tvu = [&](double depth, bool overlap) {
        cfg.column_relative_sigma_at = nullptr;
        if (overlap) {
            cfg.column_relative_sigma_at = [est](double d, double prior) {
                return est->RelativeSigmaAt(d, prior);
            };
        }
        SoundingGeometry g;
        g.R_world_vehicle = frames::RotationWorldFromRpy(0, 0, 0);
        g.angle_rad = 0;
        g.range_m = depth;
        return std::sqrt(SoundingCovariance(g, sig, cfg)(2, 2));
    };
    for (const double depth : {4.0, 8.0}) {  // the 6-10 m class stands for the shallower too
        EXPECT_NEAR(tvu(depth, true), tvu(depth, false), 0.01 * tvu(depth, false)) << depth;
        EXPECT_LT(tvu(depth, true), 0.1) << depth;
    }
    // 12 m: a class measured to 0.09 m/s, consistent with the prior, states less than it.
    EXPECT_LT(tvu(12.0, true), tvu(12.0, false));
}

// A caller reading the soundings by blocks gives the estimate only every OverlapStride-th
// sounding (the grid stage, decision 031): the same estimate bit for bit as from all of them,
// for counts around multiples of the cap.
TEST(SoundSpeedSigma, TheStridedSoundingsGiveTheEstimateOfAllOfThem) {
    std::mt19937_64 rng(5);
    std::normal_distribution<double> noise(0.0, 0.03);
    std::vector<Eigen::Vector3d> points, offsets;
    for (int pass = 0; pass < 6; ++pass) {
        for (double y = 0; y < 30; y += 0.25) {
            for (double deg = -60; deg <= 60; deg += 1.5) {
                const Eigen::Vector3d o(11.0 * std::tan(frames::DegToRad(deg)), 0, -11.0);
                const double dz = RefractionRegressor(o) * 4.0 / 1500.0;
                points.emplace_back(5.0 * pass + o.x(), y, -11.0 + dz + noise(rng));
                offsets.push_back(o);
            }
        }
    }
    SoundSpeedSigmaConfig cfg;
    int strided_and_estimated = 0;
    for (const std::size_t cap : {std::size_t{7001},
                                  std::size_t{9999},
                                  points.size() / 3,
                                  points.size() / 3 + 1,
                                  points.size()}) {
        cfg.overlap_max_soundings = cap;
        const std::size_t stride = OverlapStride(points.size(), cfg);
        std::vector<Eigen::Vector3d> p, o;
        for (std::size_t j = 0; j < points.size(); j += stride) {
            p.push_back(points[j]);
            o.push_back(offsets[j]);
        }
        EXPECT_LE(p.size(), cap);
        EXPECT_EQ(OverlapStride(p.size(), cfg), 1u);
        const OverlapSpeedEstimate all = EstimateColumnSpeedError(points, offsets, cfg);
        const OverlapSpeedEstimate taken = EstimateColumnSpeedError(p, o, cfg);
        if (stride > 1 && all.estimated()) ++strided_and_estimated;
        EXPECT_EQ(all.message, taken.message) << cap;
        EXPECT_EQ(all.soundings_used, taken.soundings_used);
        ASSERT_EQ(all.classes.size(), taken.classes.size());
        for (std::size_t c = 0; c < all.classes.size(); ++c) {
            EXPECT_EQ(all.classes[c].relative_error, taken.classes[c].relative_error) << cap;
            EXPECT_EQ(all.classes[c].relative_error_se, taken.classes[c].relative_error_se);
            EXPECT_EQ(all.classes[c].soundings, taken.classes[c].soundings);
        }
    }
    EXPECT_GT(strided_and_estimated, 0);
}

}  // namespace
}  // namespace pitmap::proc::hydro
