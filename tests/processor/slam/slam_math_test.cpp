// SPDX-License-Identifier: MIT
// Analytic Jacobians of the SLAM residuals against central differences on the manifold.
#include "processor/slam/slam_math.hpp"

#include <gtest/gtest.h>

#include <functional>

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

}  // namespace
}  // namespace pitmap::proc::slam
