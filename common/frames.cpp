// SPDX-License-Identifier: MIT
#include "common/frames.hpp"

#include <algorithm>
#include <cmath>

namespace pitmap::frames {

Eigen::Matrix3d RotationNedFromRpy(double roll, double pitch, double yaw) {
    return (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
            Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
            Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
        .toRotationMatrix();
}

Eigen::Matrix3d RotationWorldFromRpy(double roll, double pitch, double yaw) {
    return RotationEnuFromNed() * RotationNedFromRpy(roll, pitch, yaw);
}

Rpy RpyFromRotationNed(const Eigen::Matrix3d& R) {
    // R = Rz(y) Ry(p) Rx(r):  R(2,0) = -sin p,  R(2,1) = cos p sin r,  R(2,2) = cos p cos r,
    // R(1,0) = sin y cos p,  R(0,0) = cos y cos p.
    Rpy out;
    const double sp = std::clamp(-R(2, 0), -1.0, 1.0);
    out.pitch = std::asin(sp);
    const double cp = std::sqrt(R(2, 1) * R(2, 1) + R(2, 2) * R(2, 2));
    if (cp > 1e-9) {
        out.roll = std::atan2(R(2, 1), R(2, 2));
        out.yaw = std::atan2(R(1, 0), R(0, 0));
    } else {
        // Gimbal lock: only yaw - sign(p) * roll is observable; put it all in yaw.
        out.roll = 0.0;
        out.yaw = std::atan2(-R(0, 1), R(1, 1));
    }
    out.yaw = WrapPi(out.yaw);
    return out;
}

Rpy RpyFromRotationWorld(const Eigen::Matrix3d& R_world_vehicle) {
    return RpyFromRotationNed(RotationEnuFromNed().transpose() * R_world_vehicle);
}

double WrapPi(double a) {
    a = std::remainder(a, 2.0 * kPi);  // in [-pi, pi]
    if (a <= -kPi) a += 2.0 * kPi;
    return a;
}

}  // namespace pitmap::frames
