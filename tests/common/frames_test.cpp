// SPDX-License-Identifier: MIT
#include "common/frames.hpp"

#include <gtest/gtest.h>

#include "common/se3.hpp"

namespace pitmap::frames {
namespace {

constexpr double kTol = 1e-12;

TEST(Frames, IdentityAttitudeIsLevelNorth) {
    const Eigen::Matrix3d R = RotationNedFromRpy(0, 0, 0);
    EXPECT_TRUE(R.isApprox(Eigen::Matrix3d::Identity(), kTol));
    // In ENU the bow (vehicle x) points north (world y) and down (vehicle z) is world -z.
    const Eigen::Matrix3d Rw = RotationWorldFromRpy(0, 0, 0);
    EXPECT_TRUE((Rw * Eigen::Vector3d::UnitX()).isApprox(Eigen::Vector3d::UnitY(), kTol));
    EXPECT_TRUE((Rw * Eigen::Vector3d::UnitZ()).isApprox(-Eigen::Vector3d::UnitZ(), kTol));
}

TEST(Frames, SignConventions) {
    // Yaw 90 deg: bow points east.
    EXPECT_TRUE((RotationWorldFromRpy(0, 0, DegToRad(90)) * Eigen::Vector3d::UnitX())
                    .isApprox(Eigen::Vector3d::UnitX(), kTol));
    // Pitch +10 deg: bow up (world z of the bow > 0).
    EXPECT_GT((RotationWorldFromRpy(0, DegToRad(10), 0) * Eigen::Vector3d::UnitX()).z(), 0.17);
    // Roll +10 deg: starboard side down (world z of the vehicle y axis < 0).
    EXPECT_LT((RotationWorldFromRpy(DegToRad(10), 0, 0) * Eigen::Vector3d::UnitY()).z(), -0.17);
}

TEST(Frames, SpanAndEnuPermutationsAreProperRotations) {
    for (const Eigen::Matrix3d& R : {RotationEnuFromNed(), RotationVehicleFromSpan()}) {
        EXPECT_TRUE((R * R.transpose()).isApprox(Eigen::Matrix3d::Identity(), kTol));
        EXPECT_NEAR(R.determinant(), -1.0 * -1.0, kTol);  // det +1: no reflection
    }
    // SPAN forward (y) is vehicle forward (x); SPAN up is vehicle -z.
    EXPECT_TRUE(
        (RotationVehicleFromSpan() * Eigen::Vector3d::UnitY()).isApprox(Eigen::Vector3d::UnitX()));
    EXPECT_TRUE(
        (RotationVehicleFromSpan() * Eigen::Vector3d::UnitZ()).isApprox(-Eigen::Vector3d::UnitZ()));
}

TEST(Frames, RpyRoundTripOverGrid) {
    for (double r = -170; r <= 170; r += 34) {
        for (double p = -85; p <= 85; p += 17) {
            for (double y = -179; y <= 180; y += 41) {
                const Eigen::Matrix3d R =
                    RotationWorldFromRpy(DegToRad(r), DegToRad(p), DegToRad(y));
                const Rpy back = RpyFromRotationWorld(R);
                EXPECT_NEAR(back.roll, DegToRad(r), 1e-9);
                EXPECT_NEAR(back.pitch, DegToRad(p), 1e-9);
                EXPECT_NEAR(back.yaw, DegToRad(y), 1e-9);
            }
        }
    }
}

TEST(Frames, GimbalLockKeepsTheRotation) {
    for (double p : {kPi / 2, -kPi / 2}) {
        const Eigen::Matrix3d R = RotationNedFromRpy(0.3, p, 1.1);
        const Rpy back = RpyFromRotationNed(R);
        EXPECT_EQ(back.roll, 0.0);
        EXPECT_NEAR(back.pitch, p, 1e-7);
        const Eigen::Matrix3d R2 = RotationNedFromRpy(back.roll, back.pitch, back.yaw);
        EXPECT_LT(RotationAngleBetween(R, R2), 1e-7);
    }
}

TEST(Frames, WrapPi) {
    EXPECT_NEAR(WrapPi(3 * kPi), kPi, 1e-12);
    EXPECT_NEAR(WrapPi(-kPi), kPi, 1e-12);
    EXPECT_NEAR(WrapPi(2 * kPi + 0.5), 0.5, 1e-12);
    EXPECT_NEAR(WrapPi(-0.5), -0.5, 1e-15);
}

}  // namespace
}  // namespace pitmap::frames
