// SPDX-License-Identifier: MIT
// The boresight calibration's analytic derivative (processor/calib/boresight_residual) against
// central differences of the residual itself under the same right perturbation of the mount,
// R_vehicle_sonar Exp(delta), at random poses, beams and normals, and at the zero and pi
// rotations.
#include "processor/calib/boresight_residual.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace pitmap::proc::calib {
namespace {

Eigen::Vector3d RandomVector(std::mt19937& rng, double scale) {
    std::uniform_real_distribution<double> u(-scale, scale);
    return {u(rng), u(rng), u(rng)};
}

Pose RandomPose(std::mt19937& rng, double angle_scale, double t_scale) {
    return MakePose(ExpSO3(RandomVector(rng, angle_scale)), RandomVector(rng, t_scale));
}

// d r(R_vs Exp(delta)) / d delta at delta = 0, by central differences.
Eigen::RowVector3d NumericDerivative(const Pose& T_p,
                                     const Pose& T_q,
                                     const Pose& T_vs,
                                     const Eigen::Vector3d& s_p,
                                     const Eigen::Vector3d& s_q,
                                     const Eigen::Vector3d& n) {
    constexpr double h = 1e-6;
    Eigen::RowVector3d J;
    for (int k = 0; k < 3; ++k) {
        Eigen::Vector3d d = Eigen::Vector3d::Zero();
        d[k] = h;
        const auto at = [&](const Eigen::Vector3d& delta) {
            const Pose T = MakePose(T_vs.linear() * ExpSO3(delta), T_vs.translation());
            return BoresightPairResidual(T_p, T_q, T, s_p, s_q, n);
        };
        J[k] = (at(d) - at(-d)) / (2 * h);
    }
    return J;
}

TEST(BoresightResidual, IsThePointToPlaneDistance) {
    const Pose T_vs = MakePose(ExpSO3({0.01, -0.02, 0.03}), {0.2, 0.0, 0.5});
    const Pose T_p = MakePose(Eigen::Matrix3d::Identity(), {0, 0, 0});
    const Pose T_q = MakePose(Eigen::Matrix3d::Identity(), {0, 0, 0.25});
    const Eigen::Vector3d s(1.0, 2.0, 10.0), n(0, 0, 1);
    // The same beam from a vehicle 0.25 m higher: q is 0.25 m above p.
    EXPECT_NEAR(BoresightPairResidual(T_p, T_q, T_vs, s, s, n), -0.25, 1e-12);
    Eigen::RowVector3d J;
    EXPECT_NEAR(BoresightPairResidual(T_p, T_q, T_vs, s, s, n, &J), -0.25, 1e-12);
    // The same rotation on both sides: a boresight change moves p and q alike.
    EXPECT_LT(J.norm(), 1e-12);
}

TEST(BoresightResidual, AnalyticDerivativeMatchesCentralDifferences) {
    std::mt19937 rng(17);
    for (int trial = 0; trial < 200; ++trial) {
        const Pose T_vs = RandomPose(rng, trial % 4 == 0 ? 3.0 : 0.1, 1.0);
        const Pose T_p = RandomPose(rng, 3.0, 100.0);
        const Pose T_q = RandomPose(rng, 3.0, 100.0);
        const Eigen::Vector3d s_p = RandomVector(rng, 40.0);
        const Eigen::Vector3d s_q = RandomVector(rng, 40.0);
        const Eigen::Vector3d n = RandomVector(rng, 1.0).normalized();
        Eigen::RowVector3d J;
        BoresightPairResidual(T_p, T_q, T_vs, s_p, s_q, n, &J);
        const Eigen::RowVector3d Jn = NumericDerivative(T_p, T_q, T_vs, s_p, s_q, n);
        // Central differences of a residual of ~100 m with h = 1e-6: error ~ 1e-16 * 100 / h.
        EXPECT_LT((J - Jn).norm(), 1e-6 * (1.0 + Jn.norm())) << "trial " << trial << "\n"
                                                             << J << "\n"
                                                             << Jn;
    }
}

TEST(BoresightResidual, DerivativeAtZeroAndPiRotations) {
    const Eigen::Vector3d s_p(3.0, -1.0, 12.0), s_q(-2.0, 0.5, 11.0);
    const Eigen::Vector3d n = Eigen::Vector3d(0.1, -0.2, 1.0).normalized();
    for (const Eigen::Vector3d& w : {Eigen::Vector3d(0, 0, 0),
                                     Eigen::Vector3d(M_PI, 0, 0),
                                     Eigen::Vector3d(0, M_PI, 0),
                                     Eigen::Vector3d(0, 0, M_PI)}) {
        const Pose T_vs = MakePose(ExpSO3(w), {0.1, 0.2, 0.3});
        const Pose T_p = MakePose(ExpSO3({0.05, -0.03, 1.2}), {10, 5, -1});
        const Pose T_q = MakePose(ExpSO3({-0.04, 0.02, -2.0}), {12, 4, -1.1});
        Eigen::RowVector3d J;
        BoresightPairResidual(T_p, T_q, T_vs, s_p, s_q, n, &J);
        const Eigen::RowVector3d Jn = NumericDerivative(T_p, T_q, T_vs, s_p, s_q, n);
        EXPECT_LT((J - Jn).norm(), 1e-6 * (1.0 + Jn.norm())) << w.transpose();
    }
}

}  // namespace
}  // namespace pitmap::proc::calib
