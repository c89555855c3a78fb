// SPDX-License-Identifier: MIT
// The sonar's mounting on the vehicle: lever arm and boresight angles (the vehicle file's
// nominal mount, or the calibrated one). Frames and angles: docs/conventions.md.
#pragma once

#include <Eigen/Core>

#include "common/se3.hpp"

namespace pitmap::proc::survey {

// The sonar's mounting on the vehicle.
struct SonarMount {
    Eigen::Vector3d lever_arm_m = Eigen::Vector3d::Zero();  // vehicle FRD, from INS ref point
    double boresight_roll_deg = 0;  // R_vehicle_sonar = Rz(yaw) Ry(pitch) Rx(roll)
    double boresight_pitch_deg = 0;
    double boresight_yaw_deg = 0;
    Eigen::Matrix3d R_vehicle_sonar() const;
    Pose T_vehicle_sonar() const;
};

}  // namespace pitmap::proc::survey
