// SPDX-License-Identifier: MIT
// The boresight calibration's residual and its analytic derivative (the model in
// boresight.hpp): a sounding p of one pass against the tangent plane of a sounding q of
// another, both through the same mount,
//   p = T_world_vehicle_p (T_vehicle_sonar s_p),  q = T_world_vehicle_q (T_vehicle_sonar s_q),
//   r = n_p . (p - q),
// with s the beam's sonar-frame vector (m) and n_p the unit normal at p (world frame). The
// boresight is perturbed on the right, R_vehicle_sonar Exp(delta), so that
//   dr/d delta = n_p^T (-A_p [s_p]x + A_q [s_q]x),  A = R_world_vehicle R_vehicle_sonar.
// tests/processor/calib/boresight_residual_test.cpp holds it against central differences.
#pragma once

#include <Eigen/Core>

#include "common/se3.hpp"

namespace pitmap::proc::calib {

// r (metres); with `d_delta`, also dr/d delta (metres per radian).
double BoresightPairResidual(const Pose& T_world_vehicle_p,
                             const Pose& T_world_vehicle_q,
                             const Pose& T_vehicle_sonar,
                             const Eigen::Vector3d& s_p,
                             const Eigen::Vector3d& s_q,
                             const Eigen::Vector3d& n_p,
                             Eigen::RowVector3d* d_delta = nullptr);

}  // namespace pitmap::proc::calib
