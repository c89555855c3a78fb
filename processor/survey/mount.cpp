// SPDX-License-Identifier: MIT
#include "processor/survey/mount.hpp"

#include "common/frames.hpp"

namespace pitmap::proc::survey {

Eigen::Matrix3d SonarMount::R_vehicle_sonar() const {
    return frames::RotationNedFromRpy(frames::DegToRad(boresight_roll_deg),
                                      frames::DegToRad(boresight_pitch_deg),
                                      frames::DegToRad(boresight_yaw_deg));
}

Pose SonarMount::T_vehicle_sonar() const {
    return MakePose(R_vehicle_sonar(), lever_arm_m);
}

}  // namespace pitmap::proc::survey
