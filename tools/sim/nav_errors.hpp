// SPDX-License-Identifier: MIT
// Errors of the INS solution the simulated receiver reports: Gauss-Markov position and attitude
// errors at RTK quality while GNSS is good, and dead-reckoning drift (velocity random walk) in
// GPS outages that is pulled back when GNSS returns. Deterministic from a seed; sampled on a
// fixed grid and interpolated, so any output rate sees the same error process.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "tools/sim/scenario.hpp"

namespace pitmap::sim {

struct NavError {
    Eigen::Vector3d position_enu_m = Eigen::Vector3d::Zero();    // reported - true, world frame
    Eigen::Vector3d attitude_rpy_rad = Eigen::Vector3d::Zero();  // reported - true roll, pitch, yaw
    Eigen::Vector3d position_stddev_enu_m =
        Eigen::Vector3d::Zero();  // what the INS claims (1 sigma)
    Eigen::Vector3d attitude_stddev_rpy_rad = Eigen::Vector3d::Zero();
    bool gnss_available = true;  // false inside an outage
    std::uint32_t ins_status = 3;  // NovAtel INS status reported (3 INS_SOLUTION_GOOD)
};

// Thread safety: const methods may be called concurrently.
class NavErrorModel {
public:
    NavErrorModel(const NavErrorConfig& config, double duration_s, std::uint64_t seed);
    NavError At(double t_s) const;
    bool InOutage(double t_s) const;

private:
    NavErrorConfig cfg_;
    double dt_ = 0.02;
    std::vector<Eigen::Vector3d> pos_;  // per grid step
    std::vector<Eigen::Vector3d> att_;
    std::vector<Eigen::Vector3d> pos_sd_;
};

}  // namespace pitmap::sim
