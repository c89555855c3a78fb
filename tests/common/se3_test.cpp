// SPDX-License-Identifier: MIT
#include "common/se3.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace pitmap {
namespace {

constexpr double kPi = 3.14159265358979323846;

TEST(SO3, HatIsCrossProduct) {
    const Eigen::Vector3d a(1, -2, 3), b(0.5, 4, -1);
    EXPECT_TRUE((Hat(a) * b).isApprox(a.cross(b)));
}

TEST(SO3, ExpMatchesAngleAxis) {
    const Eigen::Vector3d axis = Eigen::Vector3d(1, 2, -0.5).normalized();
    for (double theta : {1e-9, 1e-4, 0.3, 1.5, 3.0, kPi}) {
        const Eigen::Matrix3d expected = Eigen::AngleAxisd(theta, axis).toRotationMatrix();
        EXPECT_TRUE(ExpSO3(axis * theta).isApprox(expected, 1e-12)) << theta;
    }
    EXPECT_TRUE(ExpSO3(Eigen::Vector3d::Zero()).isApprox(Eigen::Matrix3d::Identity()));
}

TEST(SO3, LogInvertsExpIncludingZeroAndPi) {
    const Eigen::Vector3d axis = Eigen::Vector3d(-0.3, 0.9, 0.2).normalized();
    for (double theta : {0.0, 1e-12, 1e-6, 0.7, 2.5, kPi - 1e-6}) {
        const Eigen::Vector3d w = axis * theta;
        EXPECT_TRUE(LogSO3(ExpSO3(w)).isApprox(w, 1e-9) || w.norm() < 1e-12) << theta;
        EXPECT_NEAR(LogSO3(ExpSO3(w)).norm(), theta, 1e-9);
    }
    // Exactly pi: the axis is recovered up to sign.
    const Eigen::Vector3d w = LogSO3(ExpSO3(axis * kPi));
    EXPECT_NEAR(w.norm(), kPi, 1e-9);
    EXPECT_NEAR(std::abs(w.normalized().dot(axis)), 1.0, 1e-9);
}

TEST(SO3, AngleBetween) {
    const Eigen::Matrix3d a = ExpSO3(Eigen::Vector3d(0.1, 0.2, 0.3));
    const Eigen::Matrix3d b = a * ExpSO3(Eigen::Vector3d(0, 0, 0.25));
    EXPECT_NEAR(RotationAngleBetween(a, b), 0.25, 1e-12);
    EXPECT_NEAR(RotationAngleBetween(a, a), 0.0, 1e-12);
}

TEST(Interpolation, EndpointsAndMidpoint) {
    const Pose a = MakePose(ExpSO3(Eigen::Vector3d(0, 0, 0.2)), Eigen::Vector3d(0, 0, 0));
    const Pose b = MakePose(ExpSO3(Eigen::Vector3d(0, 0, 1.0)), Eigen::Vector3d(2, 4, -6));
    EXPECT_TRUE(InterpolatePose(a, b, 0.0).isApprox(a, 1e-12));
    EXPECT_TRUE(InterpolatePose(a, b, 1.0).isApprox(b, 1e-12));
    const Pose m = InterpolatePose(a, b, 0.5);
    EXPECT_TRUE(m.translation().isApprox(Eigen::Vector3d(1, 2, -3)));
    EXPECT_TRUE(m.linear().isApprox(ExpSO3(Eigen::Vector3d(0, 0, 0.6)), 1e-12));
}

TEST(Interpolation, ShortestArcAcrossHeadingWrap) {
    // Heading 179 deg to -179 deg: the slerp goes through 180, not through 0.
    const Eigen::Matrix3d Ra = ExpSO3(Eigen::Vector3d(0, 0, 179.0 * kPi / 180));
    const Eigen::Matrix3d Rb = ExpSO3(Eigen::Vector3d(0, 0, -179.0 * kPi / 180));
    const Pose m = InterpolatePose(
        MakePose(Ra, Eigen::Vector3d::Zero()), MakePose(Rb, Eigen::Vector3d::Zero()), 0.5);
    EXPECT_LT(RotationAngleBetween(m.linear(), ExpSO3(Eigen::Vector3d(0, 0, kPi))), 1e-9);
}

TEST(Interpolation, SlerpHandlesOppositeQuaternionSigns) {
    const Eigen::Quaterniond a(ExpSO3(Eigen::Vector3d(0.1, 0, 0)));
    Eigen::Quaterniond b(ExpSO3(Eigen::Vector3d(0.3, 0, 0)));
    b.coeffs() *= -1.0;  // same rotation, other hemisphere
    const Eigen::Quaterniond m = SlerpShortest(a, b, 0.5);
    EXPECT_LT(RotationAngleBetween(m.toRotationMatrix(), ExpSO3(Eigen::Vector3d(0.2, 0, 0))),
              1e-12);
}

}  // namespace
}  // namespace pitmap
