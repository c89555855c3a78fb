// SPDX-License-Identifier: MIT
// The pieces of the posterior's perturbed-start spread (processor/slam/start_spread.cpp):
// PerturbedStart draws the INS's outage drift, StartSpread measures the runs' spread.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "processor/slam/slam.hpp"

namespace pitmap::proc::slam {
namespace {

constexpr double kT0 = 5000.0;  // GPS s of the first slice

// 10 Hz slices over 0..200 s: GNSS (0.01 m) but for an outage from 50 to 150 s whose
// horizontal sigma grows linearly to 2 m (up: to 0.5 m), then recovers at once.
std::vector<Slice> OutageSlices() {
    std::vector<Slice> out;
    for (int k = 0; k < 2000; ++k) {
        Slice s;
        s.gps_time_s = kT0 + 0.1 * k;
        const double t = 0.1 * k;
        s.T_world_vehicle.translation() = Eigen::Vector3d(t, 2.0 * t, 0.5);
        s.T_world_vehicle.linear() = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()).matrix();
        s.pose_sigma << 0.001, 0.001, 0.002, 0.01, 0.01, 0.015;
        if (t >= 50.0 && t < 150.0) {
            const double u = (t - 50.0) / 100.0;
            s.pose_sigma.tail<3>() =
                Eigen::Vector3d(0.01 + 2.0 * u, 0.01 + 2.0 * u, 0.015 + 0.5 * u);
        }
        out.push_back(s);
    }
    return out;
}

Eigen::Vector3d Offset(const std::vector<Slice>& a, const std::vector<Slice>& b, std::size_t k) {
    return b[k].T_world_vehicle.translation() - a[k].T_world_vehicle.translation();
}

TEST(StartSpread, PerturbedStartMovesOnlyWhereTheInsDrifts) {
    const std::vector<Slice> in = OutageSlices();
    const double tau = 3.0;
    const std::vector<Slice> out = PerturbedStart(in, tau, 7);
    ASSERT_EQ(out.size(), in.size());
    double outage_max = 0;
    for (std::size_t k = 0; k < in.size(); ++k) {
        const double t = in[k].gps_time_s - kT0;
        const Eigen::Vector3d d = Offset(in, out, k);
        EXPECT_TRUE(out[k].T_world_vehicle.linear().isApprox(in[k].T_world_vehicle.linear()));
        EXPECT_EQ(out[k].pose_sigma, in[k].pose_sigma);
        EXPECT_EQ(out[k].points_vehicle, in[k].points_vehicle);
        EXPECT_EQ(out[k].gps_time_s, in[k].gps_time_s);
        if (t < 50.0) {
            EXPECT_EQ(d.norm(), 0.0) << t;  // GNSS: no drift to draw
        }
        if (t >= 50.0 && t < 150.0) outage_max = std::max(outage_max, d.head<2>().norm());
        // After the recovery the drift decays as exp(-dt / tau) from its last value, whose
        // 1-sigma is at most 2 m: beyond 12 tau it is below 2 m e^-12 (a 5-sigma draw: 0.06 mm).
        if (t > 150.0 + 12 * tau) {
            EXPECT_LT(d.norm(), 1e-4) << t;
        }
    }
    EXPECT_GT(outage_max, 0.05) << "the outage was not perturbed";
    // Continuous: neighbouring slices move alike (a dead-reckoning drift, not white noise).
    for (std::size_t k = 600; k < 1400; ++k) {
        EXPECT_LT((Offset(in, out, k + 1) - Offset(in, out, k)).norm(), 0.1) << k;
    }
}

TEST(StartSpread, PerturbedStartDrawsTheReportedDrift) {
    const std::vector<Slice> in = OutageSlices();
    const std::vector<Slice> again = PerturbedStart(in, 3.0, 11);
    const std::vector<Slice> other = PerturbedStart(in, 3.0, 12);
    const std::size_t k_mid = 1000, k_late = 1400;  // t = 100 s, 140 s
    EXPECT_EQ(Offset(in, again, k_mid), Offset(in, PerturbedStart(in, 3.0, 11), k_mid));
    EXPECT_NE(Offset(in, again, k_mid), Offset(in, other, k_mid));
    // Over many draws the offset's standard deviation is the drift sigma sqrt(s^2 - f^2) per
    // component (2000 draws: the sample sd is within 10 % of it but for a 6-sigma draw).
    constexpr int kDraws = 2000;
    for (std::size_t k : {k_mid, k_late}) {
        Eigen::Vector3d ss = Eigen::Vector3d::Zero();
        for (int seed = 0; seed < kDraws; ++seed) {
            ss += Offset(in, PerturbedStart(in, 3.0, 1000 + seed), k).cwiseAbs2();
        }
        const Eigen::Vector3d sd = (ss / kDraws).cwiseSqrt();
        for (int c = 0; c < 3; ++c) {
            const double s = in[k].pose_sigma(3 + c), f = c < 2 ? 0.01 : 0.015;
            const double g = std::sqrt(s * s - f * f);
            EXPECT_NEAR(sd(c), g, 0.1 * g) << k << " " << c;
        }
    }
}

TEST(StartSpread, PerturbedStartFollowsTimeNotInputOrder) {
    std::vector<Slice> in = OutageSlices();
    std::vector<Slice> reversed(in.rbegin(), in.rend());
    const std::vector<Slice> a = PerturbedStart(in, 3.0, 5);
    const std::vector<Slice> b = PerturbedStart(reversed, 3.0, 5);
    for (std::size_t k = 0; k < in.size(); ++k) {
        EXPECT_EQ(a[k].T_world_vehicle.translation(),
                  b[in.size() - 1 - k].T_world_vehicle.translation());
    }
}

std::vector<SlamPose> Poses(const std::vector<Eigen::Vector3d>& x,
                            const std::vector<std::size_t>& input_index) {
    std::vector<SlamPose> out;
    for (std::size_t s = 0; s < x.size(); ++s) {
        SlamPose p;
        p.gps_time_s = static_cast<double>(s);
        p.T_world_vehicle.translation() = x[s];
        p.input_index = input_index[s];
        out.push_back(p);
    }
    return out;
}

TEST(StartSpread, SpreadIsTheRmsDifferenceOfTheSameSlices) {
    const std::vector<SlamPose> main =
        Poses({{0, 0, 0}, {1, 0, 0}, {2, 0, 0}}, {std::size_t{4}, std::size_t{5}, std::size_t{6}});
    // Run 1 moves slice 4 by (0.3, 0, 0.1) and slice 5 by (0, -0.4, 0); run 2 moves slice 4
    // by (-0.1, 0.2, 0) and has no slice 5; neither moves slice 6; run 2 lists its poses in
    // another order and one slice main does not have.
    const std::vector<SlamPose> run1 = Poses({{0.3, 0, 0.1}, {1, -0.4, 0}, {2, 0, 0}},
                                             {std::size_t{4}, std::size_t{5}, std::size_t{6}});
    const std::vector<SlamPose> run2 = Poses({{2, 0, 0}, {-0.1, 0.2, 0}, {9, 9, 9}},
                                             {std::size_t{6}, std::size_t{4}, std::size_t{8}});
    const std::vector<Eigen::Vector3d> s = StartSpread(main, {run1, run2});
    ASSERT_EQ(s.size(), 3u);
    EXPECT_NEAR(s[0].x(), std::sqrt((0.09 + 0.01) / 2), 1e-12);
    EXPECT_NEAR(s[0].y(), std::sqrt(0.04 / 2), 1e-12);
    EXPECT_NEAR(s[0].z(), std::sqrt(0.01 / 2), 1e-12);
    EXPECT_NEAR(s[1].y(), 0.4, 1e-12);  // one run has it
    EXPECT_NEAR(s[1].x(), 0.0, 1e-12);
    EXPECT_EQ(s[2], Eigen::Vector3d::Zero());
    // No runs: no spread.
    for (const Eigen::Vector3d& v : StartSpread(main, {})) EXPECT_EQ(v, Eigen::Vector3d::Zero());
}

}  // namespace
}  // namespace pitmap::proc::slam
