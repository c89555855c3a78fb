// SPDX-License-Identifier: MIT
// SO(3)/SE(3) helpers on Eigen: exponential and logarithm maps, interpolation.
// Conventions: T_a_b maps points of frame b into frame a (Eigen::Isometry3d).
// Tangent vectors are ordered (rotation, translation) for SE(3) where both appear.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace pitmap {

using Pose = Eigen::Isometry3d;

// Skew-symmetric matrix: Hat(a) * b == a.cross(b).
Eigen::Matrix3d Hat(const Eigen::Vector3d& v);
// Rotation vector (axis * angle, radians) -> rotation matrix. Exact for tiny angles.
Eigen::Matrix3d ExpSO3(const Eigen::Vector3d& omega);
// Rotation matrix -> rotation vector with angle in [0, pi]. Stable near 0 and near pi.
Eigen::Vector3d LogSO3(const Eigen::Matrix3d& R);
// Angle of the rotation between a and b, radians in [0, pi].
double RotationAngleBetween(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b);

// Interpolates between poses: position linearly, attitude by slerp (shortest arc).
// alpha = 0 gives a, 1 gives b; alpha outside [0, 1] extrapolates.
Pose InterpolatePose(const Pose& a, const Pose& b, double alpha);
// Same for a rotation alone.
Eigen::Quaterniond SlerpShortest(const Eigen::Quaterniond& a,
                                 const Eigen::Quaterniond& b,
                                 double alpha);

// Builds a pose from a rotation matrix and a translation.
Pose MakePose(const Eigen::Matrix3d& R, const Eigen::Vector3d& t);

}  // namespace pitmap
