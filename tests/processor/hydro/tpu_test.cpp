// SPDX-License-Identifier: MIT
// Total propagated uncertainty (processor/hydro/tpu.hpp): the range term alone at nadir; the
// analytic covariance against a Monte Carlo of the georeferencing equation with every input
// perturbed (attitude, position, lever arm, range, angle, sound speed, latency) for a tilted,
// rolled, turning vehicle; ComputeTpu over a small survey.
#include "processor/hydro/tpu.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include "common/frames.hpp"

namespace pitmap::proc::hydro {
namespace {

SensorErrorModel RangeOnly() {
    SensorErrorModel m;
    m.beam_angle_sigma_deg = 0;
    m.surface_sound_speed_sigma_mps = 0;
    m.mean_sound_speed_sigma_mps = 0;
    m.position_noise_m = 0;
    m.heave_sigma_m = 0;
    m.latency_sigma_s = 0;
    m.lever_arm_sigma_m = 0;
    m.boresight_sigma_deg = 0;
    return m;
}

TEST(Tpu, NadirRangeTermIsTheRangeNoise) {
    TpuConfig cfg;
    cfg.model = RangeOnly();
    SoundingGeometry g;
    g.R_world_vehicle = frames::RotationWorldFromRpy(0, 0, 0.3);
    g.range_m = 20;
    const Eigen::Matrix3d C = SoundingCovariance(g, PingSigma{}, cfg);
    const double sr = 0.02 + 0.002 * 20;
    EXPECT_NEAR(std::sqrt(C(2, 2)), sr, 1e-12);
    EXPECT_NEAR(C(0, 0) + C(1, 1), 0.0, 1e-18);
}

// The calibrated boresight sigma replaces the model's per axis, never adds to it.
TEST(Tpu, CalibratedBoresightSigmaReplacesTheModels) {
    TpuConfig cfg;
    SoundingGeometry g;
    g.R_world_vehicle = frames::RotationWorldFromRpy(0.05, -0.03, 0.7);
    g.range_m = 25;
    g.angle_rad = 0.6;
    const Eigen::Matrix3d model = SoundingCovariance(g, PingSigma{}, cfg);
    TpuConfig same = cfg;
    same.boresight_sigma_rpy_deg = {cfg.model.boresight_sigma_deg,
                                    cfg.model.boresight_sigma_deg,
                                    std::numeric_limits<double>::quiet_NaN()};
    EXPECT_LT((SoundingCovariance(g, PingSigma{}, same) - model).norm(), 1e-15);
    TpuConfig zero = cfg;
    zero.boresight_sigma_rpy_deg = {0.0, 0.0, 0.0};
    TpuConfig no_prior = cfg;
    no_prior.model.boresight_sigma_deg = 0.0;
    EXPECT_LT(
        (SoundingCovariance(g, PingSigma{}, zero) - SoundingCovariance(g, PingSigma{}, no_prior))
            .norm(),
        1e-15);
    EXPECT_LT(SoundingCovariance(g, PingSigma{}, zero).trace(), model.trace());
    TpuConfig bad = cfg;
    bad.boresight_sigma_rpy_deg[1] = -0.1;
    EXPECT_FALSE(bad.Validate().empty());
}

TEST(Tpu, AnalyticCovarianceMatchesMonteCarloOfTheGeoreferencing) {
    TpuConfig cfg;
    cfg.model.beam_angle_sigma_deg = 0.1;
    cfg.model.latency_sigma_s = 0.01;
    cfg.model.heave_sigma_m = 0.03;
    cfg.model.boresight_sigma_deg = 0.05;
    cfg.clock_sigma_s = 0.005;
    PingSigma sig;
    sig.position_enu_m = Eigen::Vector3d(0.02, 0.03, 0.05);
    sig.attitude_rpy_rad =
        Eigen::Vector3d(frames::DegToRad(0.2), frames::DegToRad(0.15), frames::DegToRad(0.5));
    const double roll = 0.08, pitch = -0.05, yaw = 2.1;
    SoundingGeometry g;
    g.R_world_vehicle = frames::RotationWorldFromRpy(roll, pitch, yaw);
    g.R_vehicle_sonar = frames::RotationNedFromRpy(0.01, 0.02, -0.03);
    g.lever_arm_m = Eigen::Vector3d(0.8, 0.1, 0.25);
    g.range_m = 30;
    g.angle_rad = frames::DegToRad(50);
    g.tilt_rad = frames::DegToRad(5);
    g.velocity_mps = Eigen::Vector3d(1.2, -0.4, 0.05);
    g.angular_rate_radps = Eigen::Vector3d(0.05, -0.03, 0.1);
    const Eigen::Matrix3d C = SoundingCovariance(g, sig, cfg);

    const SensorErrorModel& m = cfg.model;
    const double c = cfg.sound_speed_mps;
    const auto sonar_point = [&](double r, double th) {
        return georef::BeamVectorSonar(r, th, g.tilt_rad);
    };
    const Eigen::Vector3d p0 =
        g.R_world_vehicle *
        (g.lever_arm_m + g.R_vehicle_sonar * sonar_point(g.range_m, g.angle_rad));
    std::mt19937_64 rng(7);
    std::normal_distribution<double> n01(0, 1);
    const int N = 40000;
    Eigen::Matrix3d S = Eigen::Matrix3d::Zero();
    const double bore = frames::DegToRad(m.boresight_sigma_deg);
    for (int k = 0; k < N; ++k) {
        const double r = g.range_m +
                         (m.range_sigma_m + m.range_sigma_fraction * g.range_m) * n01(rng) +
                         g.range_m * m.mean_sound_speed_sigma_mps / c * n01(rng);
        const double th = g.angle_rad + frames::DegToRad(m.beam_angle_sigma_deg) * n01(rng) +
                          std::tan(g.angle_rad) * m.surface_sound_speed_sigma_mps / c * n01(rng);
        const Eigen::Matrix3d R = frames::RotationWorldFromRpy(
            roll + std::hypot(sig.attitude_rpy_rad[0], bore) * n01(rng),
            pitch + std::hypot(sig.attitude_rpy_rad[1], bore) * n01(rng),
            yaw + std::hypot(sig.attitude_rpy_rad[2], bore) * n01(rng));
        const Eigen::Vector3d L =
            g.lever_arm_m + m.lever_arm_sigma_m * Eigen::Vector3d(n01(rng), n01(rng), n01(rng));
        // Latency: the pose of a time dt away.
        const double dt = std::hypot(m.latency_sigma_s, cfg.clock_sigma_s) * n01(rng);
        const Eigen::Matrix3d Rt =
            Eigen::AngleAxisd(g.angular_rate_radps.norm() * dt, g.angular_rate_radps.normalized())
                .toRotationMatrix() *
            R;
        Eigen::Vector3d t = g.velocity_mps * dt;
        for (int i = 0; i < 3; ++i) {
            t[i] += std::hypot(sig.position_enu_m[i], m.position_noise_m) * n01(rng);
        }
        t.z() += m.heave_sigma_m * n01(rng);
        const Eigen::Vector3d p = t + Rt * (L + g.R_vehicle_sonar * sonar_point(r, th));
        const Eigen::Vector3d e = p - p0;
        S += e * e.transpose();
    }
    S /= N;
    // Sampling error of a variance from 40000 draws: ~0.7 % (1 sigma); linearisation: < 1 %.
    EXPECT_NEAR(std::sqrt(C(2, 2)), std::sqrt(S(2, 2)), 0.03 * std::sqrt(S(2, 2)));
    EXPECT_NEAR(std::sqrt(C(0, 0)), std::sqrt(S(0, 0)), 0.03 * std::sqrt(S(0, 0)));
    EXPECT_NEAR(std::sqrt(C(1, 1)), std::sqrt(S(1, 1)), 0.03 * std::sqrt(S(1, 1)));
    EXPECT_NEAR(C(0, 2), S(0, 2), 0.05 * std::sqrt(S(0, 0) * S(2, 2)));
    // The terms add up to the covariance.
    std::array<Eigen::Matrix3d, kNumTpuTerms> terms;
    (void)SoundingCovariance(g, sig, cfg, &terms);
    Eigen::Matrix3d sum = Eigen::Matrix3d::Zero();
    for (const auto& t : terms) sum += t;
    EXPECT_TRUE(sum.isApprox(C, 1e-12));
    EXPECT_GT(terms[static_cast<int>(TpuTerm::kAttitude)](2, 2), 0.0);
    EXPECT_GT(terms[static_cast<int>(TpuTerm::kLatency)](0, 0), 0.0);
}

TEST(Tpu, ComputeTpuGivesOneValuePerSoundingAndTermSharesSumToOne) {
    georef::GeorefResult geo;
    survey::SonarMount mount;
    mount.lever_arm_m = Eigen::Vector3d(0.8, 0, 0.25);
    for (int k = 0; k < 20; ++k) {
        georef::GeorefPing p;
        p.utime_gps = 1'000'000'000'000 + k * 100'000;
        p.T_world_vehicle = MakePose(frames::RotationWorldFromRpy(0.02 * std::sin(k), 0, 0.5),
                                     Eigen::Vector3d(0.12 * k, 0, 0));
        geo.pings.push_back(p);
        for (int b = 0; b < 11; ++b) {
            const double th = frames::DegToRad(-60 + 12 * b);
            const double r = 20 / std::cos(th);
            geo.points.position_world.push_back(
                p.T_world_vehicle * (mount.T_vehicle_sonar() * georef::BeamVectorSonar(r, th, 0)));
            geo.points.ping.push_back(static_cast<std::uint32_t>(k));
            geo.points.beam.push_back(static_cast<std::uint16_t>(b));
            geo.points.range_m.push_back(static_cast<float>(r));
            geo.points.angle_rad.push_back(static_cast<float>(th));
        }
    }
    TpuConfig cfg;
    PingSigma s;
    s.position_enu_m = Eigen::Vector3d(0.01, 0.01, 0.015);
    s.attitude_rpy_rad = Eigen::Vector3d::Constant(frames::DegToRad(0.02));
    const TpuResult r = ComputeTpu(geo, mount, std::vector<PingSigma>(20, s), cfg);
    ASSERT_EQ(r.tvu_95_m.size(), geo.points.size());
    double share = 0;
    for (double x : r.tvu_variance_share) share += x;
    EXPECT_NEAR(share, 1.0, 1e-9);
    // Outer beams are less certain vertically than the nadir beam.
    EXPECT_GT(r.tvu_95_m[0], r.tvu_95_m[5]);
    EXPECT_GT(r.tvu_95_m[5], 1.96 * 0.015);
    // A sigma list of the wrong length is reported, not a crash.
    const TpuResult bad = ComputeTpu(geo, mount, std::vector<PingSigma>(3, s), cfg);
    EXPECT_NE(bad.message.find("3 ping sigmas for 20 pings"), std::string::npos) << bad.message;
    TpuConfig invalid;
    invalid.model.range_sigma_m = -1;
    invalid.sound_speed_mps = 0;
    EXPECT_EQ(invalid.Validate().size(), 2u);
}

bool SameFloats(const std::vector<float>& a, const std::vector<float>& b) {
    return a.size() == b.size() &&
           (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0);
}

// The TPU of a view read a block at a time (decision 031) is ComputeTpu's of the whole view bit
// for bit: blocks of 1, of one sounding less and more than a share chunk, an odd size, the
// whole view; the pings' sigmas differ so that every sounding's value is its own.
TEST(Tpu, BlocksOfTheViewGiveTheWholeViewsTpuBitForBit) {
    georef::GeorefResult geo;
    survey::SonarMount mount;
    mount.lever_arm_m = Eigen::Vector3d(0.8, 0.1, 0.25);
    std::vector<PingSigma> sigma;
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-1, 1);
    for (int k = 0; k < 43; ++k) {
        georef::GeorefPing p;
        p.utime_gps = 1'000'000'000'000 + k * 100'000;
        p.T_world_vehicle =
            MakePose(frames::RotationWorldFromRpy(0.05 * u(rng), 0.03 * u(rng), 0.5 + 0.01 * k),
                     Eigen::Vector3d(0.12 * k, 0.01 * k * k, 0.02 * u(rng)));
        p.profile_tilt_rad = 0.01 * u(rng);
        geo.pings.push_back(p);
        PingSigma s;
        s.position_enu_m = Eigen::Vector3d(0.01, 0.012, 0.015) * (1 + 0.5 * u(rng));
        s.attitude_rpy_rad = Eigen::Vector3d::Constant(frames::DegToRad(0.02 + 0.01 * u(rng)));
        sigma.push_back(s);
        for (int b = 0; b < 480; ++b) {
            const double th = frames::DegToRad(-70 + 140.0 * b / 479);
            const double r = (15 + 5 * u(rng)) / std::cos(th);
            geo.points.position_world.push_back(
                p.T_world_vehicle * (mount.T_vehicle_sonar() * georef::BeamVectorSonar(r, th, 0)));
            geo.points.ping.push_back(static_cast<std::uint32_t>(k));
            geo.points.beam.push_back(static_cast<std::uint16_t>(b));
            geo.points.range_m.push_back(static_cast<float>(r));
            geo.points.angle_rad.push_back(static_cast<float>(th));
        }
    }
    TpuConfig cfg;
    const std::size_t n = geo.points.size();
    ASSERT_GT(n, 2 * TpuByBlocks::kShareChunk);
    const TpuResult whole = ComputeTpu(geo, mount, sigma, cfg);
    for (const std::size_t block : {std::size_t{1},
                                    TpuByBlocks::kShareChunk - 1,
                                    TpuByBlocks::kShareChunk + 1,
                                    std::size_t{10007},
                                    n}) {
        TpuByBlocks tpu(geo.pings, mount, sigma, cfg, n);
        for (std::size_t first = 0; first < n; first += block) {
            tpu.Add(georef::SliceOf(geo.points, first, std::min(block, n - first)), first);
        }
        const TpuResult r = tpu.Finish();
        EXPECT_TRUE(SameFloats(r.tvu_95_m, whole.tvu_95_m)) << block;
        EXPECT_TRUE(SameFloats(r.thu_95_m, whole.thu_95_m)) << block;
        EXPECT_TRUE(SameFloats(r.sigma_v_common_m, whole.sigma_v_common_m)) << block;
        EXPECT_TRUE(SameFloats(r.sigma_h_common_m, whole.sigma_h_common_m)) << block;
        for (int t = 0; t < kNumTpuTerms; ++t) {
            EXPECT_EQ(r.tvu_variance_share[t], whole.tvu_variance_share[t]) << block << " " << t;
        }
        EXPECT_EQ(r.median_tvu_95_m, whole.median_tvu_95_m);
        EXPECT_EQ(r.median_thu_95_m, whole.median_thu_95_m);
        EXPECT_EQ(r.message, whole.message);
    }
    // A block out of order is not taken (its soundings stay 0): blocks go in the view's order.
    TpuByBlocks skipped(geo.pings, mount, sigma, cfg, n);
    skipped.Add(georef::SliceOf(geo.points, 100, 10), 100);
    EXPECT_EQ(skipped.Finish().tvu_95_m[100], 0.0f);
}

// The pass-common parts (what CUBE's node does not average over one pass's soundings): with
// the INS's position sigma alone they are that sigma; the range noise, the beam pointing and
// the INS's white output noise are not in them.
TEST(Tpu, PassCommonPartsAreThePositionSigmaWithoutTheNoiseTerms) {
    georef::GeorefResult geo;
    survey::SonarMount mount;
    georef::GeorefPing p;
    p.utime_gps = 1'000'000'000'000;
    p.T_world_vehicle = MakePose(Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero());
    geo.pings.push_back(p);
    for (int b = 0; b < 5; ++b) {
        const double th = frames::DegToRad(-50 + 25 * b);
        const double r = 10 / std::cos(th);
        geo.points.position_world.push_back(
            p.T_world_vehicle * (mount.T_vehicle_sonar() * georef::BeamVectorSonar(r, th, 0)));
        geo.points.ping.push_back(0);
        geo.points.beam.push_back(static_cast<std::uint16_t>(b));
        geo.points.range_m.push_back(static_cast<float>(r));
        geo.points.angle_rad.push_back(static_cast<float>(th));
    }
    TpuConfig cfg;
    SensorErrorModel& m = cfg.model;
    m = SensorErrorModel{};
    m.range_sigma_m = 0.02;
    m.range_sigma_fraction = 0.002;
    m.beam_angle_sigma_deg = 0.05;
    m.position_noise_m = 0.005;
    m.boresight_sigma_deg = 0;
    m.surface_sound_speed_sigma_mps = 0;
    m.mean_sound_speed_sigma_mps = 0;
    m.heave_sigma_m = 0;
    m.latency_sigma_s = 0;
    m.lever_arm_sigma_m = 0;
    PingSigma s;
    s.position_enu_m = Eigen::Vector3d(0.01, 0.02, 0.015);
    s.attitude_rpy_rad.setZero();
    const TpuResult r = ComputeTpu(geo, mount, {s}, cfg);
    ASSERT_EQ(r.sigma_h_common_m.size(), 5u);
    for (std::size_t j = 0; j < 5; ++j) {
        EXPECT_NEAR(r.sigma_v_common_m[j], 0.015, 1e-6) << j;
        EXPECT_NEAR(r.sigma_h_common_m[j], std::sqrt((0.01 * 0.01 + 0.02 * 0.02) / 2), 1e-6) << j;
        // The whole horizontal sigma holds the noise terms besides (off nadir the range noise
        // and the pointing move the sounding sideways).
        EXPECT_GT(r.thu_95_m[j] / kThu95, r.sigma_h_common_m[j] + 1e-4) << j;
    }
}

TEST(Tpu, InsSigmaIsTheNearestRecordElseTheModels) {
    SensorErrorModel m;
    const PingSigma fb = FallbackSigma(m);
    EXPECT_NEAR(fb.attitude_rpy_rad[0], frames::DegToRad(0.015), 1e-15);
    EXPECT_NEAR(fb.attitude_rpy_rad[2], frames::DegToRad(0.04), 1e-15);
    EXPECT_DOUBLE_EQ(fb.position_enu_m[0], 0.01);
    EXPECT_DOUBLE_EQ(fb.position_enu_m[2], 0.015);
    const float nan = std::nanf("");
    // Records at 1 s and 2 s; the one at 2 s reports no height sigma.
    const std::vector<survey::NavStdDev> s = {{1'000'000, 0.1f, 0.2f, 0.3f, 1.f, 2.f, 3.f},
                                              {2'000'000, 0.4f, 0.5f, nan, 4.f, 5.f, 6.f}};
    bool from_ins = false;
    PingSigma a = InsSigmaAt(s, 1'400'000, 5.0, fb, &from_ins);
    EXPECT_TRUE(from_ins);
    EXPECT_NEAR(a.position_enu_m[0], 0.2, 1e-6);  // east = longitude sigma
    EXPECT_NEAR(a.position_enu_m[1], 0.1, 1e-6);
    EXPECT_NEAR(a.position_enu_m[2], 0.3, 1e-6);
    EXPECT_NEAR(a.attitude_rpy_rad[2], frames::DegToRad(3.0), 1e-7);
    a = InsSigmaAt(s, 1'600'000, 5.0, fb);
    EXPECT_NEAR(a.position_enu_m[0], 0.5, 1e-6);
    EXPECT_DOUBLE_EQ(a.position_enu_m[2], fb.position_enu_m[2]);  // not reported: the model's
    a = InsSigmaAt(s, 60'000'000, 5.0, fb, &from_ins);            // too far from any record
    EXPECT_FALSE(from_ins);
    EXPECT_EQ(a.position_enu_m, fb.position_enu_m);
    EXPECT_EQ(a.attitude_rpy_rad, fb.attitude_rpy_rad);
    InsSigmaAt({}, 0, 5.0, fb, &from_ins);
    EXPECT_FALSE(from_ins);
}

}  // namespace
}  // namespace pitmap::proc::hydro
