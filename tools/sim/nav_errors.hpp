// SPDX-License-Identifier: MIT
// Errors of the INS solution the simulated receiver reports: Gauss-Markov position and attitude
// errors at RTK quality while GNSS is good, and dead-reckoning drift (velocity random walk) in
// GPS outages that is pulled back when GNSS returns. Deterministic from a seed; sampled on a
// fixed grid and interpolated, so any output rate sees the same error process.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <mutex>
#include <random>
#include <vector>

#include "tools/sim/scenario.hpp"

namespace pitmap::sim {

struct NavError {
    Eigen::Vector3d position_enu_m = Eigen::Vector3d::Zero();    // reported - true, world frame
    Eigen::Vector3d attitude_rpy_rad = Eigen::Vector3d::Zero();  // reported - true roll, pitch, yaw
    Eigen::Vector3d position_stddev_enu_m =
        Eigen::Vector3d::Zero();  // what the INS claims (1 sigma)
    Eigen::Vector3d attitude_stddev_rpy_rad = Eigen::Vector3d::Zero();
    bool gnss_available = true;    // false inside an outage
    std::uint32_t ins_status = 3;  // NovAtel INS status reported (3 INS_SOLUTION_GOOD)
};

// The error process is generated forward from the seed on demand and only a window of it is
// kept (two chunks of kChunkSteps samples, ~160 s, ~600 kB), so an hours-long survey does not
// hold its whole error series: queries in increasing time (the receiver's) cost one step each;
// a query before the window regenerates from the start (the same values: deterministic).
// Thread safety: const methods may be called concurrently (the window is behind a mutex).
class NavErrorModel {
public:
    NavErrorModel(const NavErrorConfig& config, double duration_s, std::uint64_t seed);
    NavError At(double t_s) const;
    bool InOutage(double t_s) const;

    static constexpr std::size_t kChunkSteps = 4096;  // 81.92 s at dt = 0.02 s

private:
    struct Sample {
        Eigen::Vector3d pos, att, pos_sd;
    };
    // The forward state of the error process: exactly what one step of it needs.
    struct Generator {
        std::mt19937_64 rng, white_rng;
        std::normal_distribution<double> g;
        Eigen::Vector3d gm_p, gm_a, drift, drift_vel;
        double outage_start = -1;
        std::size_t next_k = 0;
    };
    void Restart() const;                         // the generator at step 0 (mu_ held)
    Sample Step() const;                          // the next sample (mu_ held)
    const Sample& SampleAt(std::size_t k) const;  // from the window, generating (mu_ held)

    NavErrorConfig cfg_;
    double dt_ = 0.02;
    std::uint64_t seed_ = 0;
    std::size_t n_ = 0;  // samples over the duration
    double phi_p_ = 0, phi_a_ = 0, q_p_ = 0, q_a_ = 0;
    Eigen::Vector3d sig_p_, sig_a_;
    mutable std::mutex mu_;
    mutable Generator gen_;
    mutable std::vector<Sample> window_;  // samples [window_k0_, window_k0_ + size)
    mutable std::size_t window_k0_ = 0;
};

}  // namespace pitmap::sim
