// SPDX-License-Identifier: MIT
#include "processor/calib/boresight_residual.hpp"

namespace pitmap::proc::calib {

double BoresightPairResidual(const Pose& T_world_vehicle_p,
                             const Pose& T_world_vehicle_q,
                             const Pose& T_vehicle_sonar,
                             const Eigen::Vector3d& s_p,
                             const Eigen::Vector3d& s_q,
                             const Eigen::Vector3d& n_p,
                             Eigen::RowVector3d* d_delta) {
    const Eigen::Vector3d p = T_world_vehicle_p * (T_vehicle_sonar * s_p);
    const Eigen::Vector3d q = T_world_vehicle_q * (T_vehicle_sonar * s_q);
    if (d_delta != nullptr) {
        // d(R Exp(delta) s)/d delta = -R [s]x at delta = 0.
        const Eigen::Matrix3d A_p = T_world_vehicle_p.linear() * T_vehicle_sonar.linear();
        const Eigen::Matrix3d A_q = T_world_vehicle_q.linear() * T_vehicle_sonar.linear();
        *d_delta = n_p.transpose() * (-A_p * Hat(s_p) + A_q * Hat(s_q));
    }
    return n_p.dot(p - q);
}

}  // namespace pitmap::proc::calib
