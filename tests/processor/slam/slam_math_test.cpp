// SPDX-License-Identifier: MIT
// Analytic Jacobians of the SLAM residuals against central differences on the manifold.
#include "processor/slam/slam_math.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <random>
#include <vector>

namespace pitmap::proc::slam {
namespace {

Pose RandomPose(int seed, double angle_scale = 1.0) {
    std::srand(static_cast<unsigned>(seed));
    const Eigen::Vector3d w = Eigen::Vector3d::Random() * angle_scale;
    const Eigen::Vector3d t = Eigen::Vector3d::Random() * 50.0;
    return MakePose(ExpSO3(w), t);
}

// Numerical Jacobian of f(ApplyIncrement(T, d)) at d = 0.
template <int M>
Eigen::Matrix<double, M, 6> NumericJacobian(
    const std::function<Eigen::Matrix<double, M, 1>(const Pose&)>& f, const Pose& T) {
    Eigen::Matrix<double, M, 6> J;
    const double h = 1e-6;
    for (int k = 0; k < 6; ++k) {
        Vector6d d = Vector6d::Zero();
        d(k) = h;
        J.col(k) = (f(ApplyIncrement(T, d)) - f(ApplyIncrement(T, -d))) / (2 * h);
    }
    return J;
}

TEST(SlamMath, JacobianInversesAreInversesOfTheJacobians) {
    for (const double angle : {0.0, 1e-6, 0.3, 2.0, 3.1}) {
        const Eigen::Vector3d phi = Eigen::Vector3d(0.3, -0.5, 0.8).normalized() * angle;
        // LogSO3(Exp(phi) Exp(d)) - phi ~= JrInv d: check by finite differences.
        Eigen::Matrix3d J;
        const double h = 1e-7;
        for (int k = 0; k < 3; ++k) {
            Eigen::Vector3d d = Eigen::Vector3d::Zero();
            d(k) = h;
            J.col(k) =
                (LogSO3(ExpSO3(phi) * ExpSO3(d)) - LogSO3(ExpSO3(phi) * ExpSO3(-d))) / (2 * h);
        }
        EXPECT_TRUE(J.isApprox(RightJacobianInverseSO3(phi), 1e-6)) << "angle " << angle;
        for (int k = 0; k < 3; ++k) {
            Eigen::Vector3d d = Eigen::Vector3d::Zero();
            d(k) = h;
            J.col(k) =
                (LogSO3(ExpSO3(d) * ExpSO3(phi)) - LogSO3(ExpSO3(-d) * ExpSO3(phi))) / (2 * h);
        }
        EXPECT_TRUE(J.isApprox(LeftJacobianInverseSO3(phi), 1e-6)) << "angle " << angle;
    }
}

TEST(SlamMath, PointPairJacobians) {
    const Pose Ta = RandomPose(1), Tb = RandomPose(2);
    const Eigen::Vector3d xa(1.0, -2.0, 20.0), xb(-3.0, 0.5, 18.0);
    Matrix36d Ja, Jb;
    PointPairResidual(Ta, xa, Tb, xb, &Ja, &Jb);
    const auto fa = [&](const Pose& T) { return PointPairResidual(T, xa, Tb, xb); };
    const auto fb = [&](const Pose& T) { return PointPairResidual(Ta, xa, T, xb); };
    EXPECT_TRUE(Ja.isApprox(NumericJacobian<3>(fa, Ta), 1e-6));
    EXPECT_TRUE(Jb.isApprox(NumericJacobian<3>(fb, Tb), 1e-6));
}

TEST(SlamMath, PointToPlaneJacobians) {
    const Pose Ta = RandomPose(3), Tb = RandomPose(4);
    const Eigen::Vector3d xa(1.0, -2.0, 20.0), xb(-3.0, 0.5, 18.0);
    const Eigen::Vector3d n = Eigen::Vector3d(0.1, 0.2, 1.0).normalized();
    Matrix16d Ja, Jb;
    PointToPlaneResidual(Ta, xa, Tb, xb, n, &Ja, &Jb);
    const auto fa = [&](const Pose& T) {
        return Eigen::Matrix<double, 1, 1>(PointToPlaneResidual(T, xa, Tb, xb, n));
    };
    const auto fb = [&](const Pose& T) {
        return Eigen::Matrix<double, 1, 1>(PointToPlaneResidual(Ta, xa, T, xb, n));
    };
    EXPECT_TRUE(Ja.isApprox(NumericJacobian<1>(fa, Ta), 1e-6));
    EXPECT_TRUE(Jb.isApprox(NumericJacobian<1>(fb, Tb), 1e-6));
}

TEST(SlamMath, RelativeMotionZeroAtMeasurementAndJacobians) {
    const Pose Ti = RandomPose(5), Tj = RandomPose(6);
    const RelativeMotion m = MeasureRelativeMotion(Ti, Tj);
    EXPECT_LT(RelativeMotionResidual(Ti, Tj, m).norm(), 1e-12);
    // Away from the measurement, including a large rotation error (near pi).
    for (const double scale : {0.05, 1.0, 2.9}) {
        Vector6d d;
        d << Eigen::Vector3d(0.2, -0.4, 0.9).normalized() * scale, 0.3, -1.0, 2.0;
        const Pose Ti2 = ApplyIncrement(Ti, d);
        Matrix6d Ji, Jj;
        RelativeMotionResidual(Ti2, Tj, m, &Ji, &Jj);
        const auto fi = [&](const Pose& T) { return RelativeMotionResidual(T, Tj, m); };
        const auto fj = [&](const Pose& T) { return RelativeMotionResidual(Ti2, T, m); };
        EXPECT_TRUE(Ji.isApprox(NumericJacobian<6>(fi, Ti2), 1e-5)) << scale;
        EXPECT_TRUE(Jj.isApprox(NumericJacobian<6>(fj, Tj), 1e-5)) << scale;
    }
}

TEST(SlamMath, AbsolutePoseJacobian) {
    const Pose T = RandomPose(7), T0 = RandomPose(8);
    Matrix6d J;
    AbsolutePoseResidual(T, T0, &J);
    const auto f = [&](const Pose& X) { return AbsolutePoseResidual(X, T0); };
    EXPECT_TRUE(J.isApprox(NumericJacobian<6>(f, T), 1e-5));
    EXPECT_LT(AbsolutePoseResidual(T0, T0).norm(), 1e-12);
}

// The INS's per-output white noise from the track's second differences: a vehicle turning at
// 1.5 m/s on a 20 m circle, heaving 5 cm in 3.5 s waves, at 10 Hz with some outputs missing
// (uneven steps), plus white noise of 5 mm (horizontal) and 8 mm (vertical): the estimate is
// within 10 % of it, and sub-mm from the motion alone.
TEST(SlamMath, PositionWhiteNoiseFromTheTracksSecondDifferences) {
    std::mt19937 rng(7);
    std::normal_distribution<double> g(0.0, 1.0);
    std::vector<double> t;
    std::vector<Pose> clean, noisy;
    for (int k = 0; k < 6000; ++k) {
        if (k % 37 == 5) continue;  // a missing output: a step of 0.2 s next to one of 0.1 s
        const double ts = 0.1 * k;
        const double a = 1.5 * ts / 20.0;
        const Eigen::Vector3d x(
            20.0 * std::cos(a), 20.0 * std::sin(a), 0.05 * std::sin(2.0 * M_PI * ts / 3.5));
        t.push_back(ts);
        clean.push_back(MakePose(Eigen::Matrix3d::Identity(), x));
        noisy.push_back(
            MakePose(Eigen::Matrix3d::Identity(),
                     x + Eigen::Vector3d(0.005 * g(rng), 0.005 * g(rng), 0.008 * g(rng))));
    }
    const Eigen::Vector3d s = PositionWhiteNoise(t, noisy);
    EXPECT_NEAR(s.x(), 0.005, 0.0005);
    EXPECT_NEAR(s.y(), 0.005, 0.0005);
    EXPECT_NEAR(s.z(), 0.008, 0.0008);
    EXPECT_LT(PositionWhiteNoise(t, clean).maxCoeff(), 0.001);
    // Too few triples, or steps beyond max_step_s (a 1 Hz INS log): nothing is stated.
    const std::vector<double> t_short(t.begin(), t.begin() + 50);
    const std::vector<Pose> p_short(noisy.begin(), noisy.begin() + 50);
    EXPECT_EQ(PositionWhiteNoise(t_short, p_short), Eigen::Vector3d::Zero());
    std::vector<double> t_slow = t;
    for (double& v : t_slow) v *= 10.0;
    EXPECT_EQ(PositionWhiteNoise(t_slow, noisy), Eigen::Vector3d::Zero());
}

}  // namespace
}  // namespace pitmap::proc::slam
