// SPDX-License-Identifier: MIT
#include "tools/sim/nav_errors.hpp"

#include <algorithm>
#include <cmath>
#include <random>

#include "common/frames.hpp"

namespace pitmap::sim {

NavErrorModel::NavErrorModel(const NavErrorConfig& cfg, double duration_s, std::uint64_t seed)
    : cfg_(cfg) {
    const auto n = static_cast<std::size_t>(std::ceil(std::max(duration_s, 0.0) / dt_)) + 2;
    pos_.resize(n);
    att_.resize(n);
    pos_sd_.resize(n);
    std::mt19937_64 rng(seed ^ 0xA11E5ull);
    std::normal_distribution<double> g(0.0, 1.0);
    std::mt19937_64 white_rng(seed ^
                              0x3A17Eull);  // own stream: white noise does not shift the walks

    // First-order Gauss-Markov: x' = phi x + sigma sqrt(1 - phi^2) w keeps variance sigma^2.
    const double phi_p = std::exp(-dt_ / cfg.position_gm_tau_s);
    const double phi_a = std::exp(-dt_ / cfg.attitude_gm_tau_s);
    const double q_p = std::sqrt(1 - phi_p * phi_p), q_a = std::sqrt(1 - phi_a * phi_a);
    const Eigen::Vector3d sig_p(
        cfg.position_gm_sigma_m, cfg.position_gm_sigma_m, cfg.height_gm_sigma_m);
    const Eigen::Vector3d sig_a(frames::DegToRad(cfg.attitude_gm_sigma_deg),
                                frames::DegToRad(cfg.attitude_gm_sigma_deg),
                                frames::DegToRad(cfg.heading_gm_sigma_deg));
    Eigen::Vector3d gm_p(sig_p.x() * g(rng), sig_p.y() * g(rng), sig_p.z() * g(rng));
    Eigen::Vector3d gm_a(sig_a.x() * g(rng), sig_a.y() * g(rng), sig_a.z() * g(rng));
    Eigen::Vector3d drift = Eigen::Vector3d::Zero();      // dead-reckoning position error
    Eigen::Vector3d drift_vel = Eigen::Vector3d::Zero();  // its rate
    const Eigen::Vector3d rw(1.0, 1.0, cfg.outage_vertical_fraction);
    double outage_start = -1;
    for (std::size_t k = 0; k < n; ++k) {
        const double t = static_cast<double>(k) * dt_;
        for (int i = 0; i < 3; ++i) {
            gm_p[i] = phi_p * gm_p[i] + sig_p[i] * q_p * g(rng);
            gm_a[i] = phi_a * gm_a[i] + sig_a[i] * q_a * g(rng);
        }
        Eigen::Vector3d sd = sig_p;
        if (InOutage(t)) {
            if (outage_start < 0) outage_start = t;
            for (int i = 0; i < 3; ++i) {
                drift_vel[i] += rw[i] * cfg.outage_velocity_random_walk_mps_per_sqrt_s *
                                std::sqrt(dt_) * g(rng);
            }
            drift += drift_vel * dt_;
            // Integrated random walk: sigma(t) = q t^1.5 / sqrt(3); the INS reports it grows.
            const double te = t - outage_start;
            const double grow =
                cfg.outage_velocity_random_walk_mps_per_sqrt_s * std::pow(te, 1.5) / std::sqrt(3.0);
            sd = (sig_p.array().square() + (rw * grow).array().square()).sqrt();
        } else {
            outage_start = -1;
            // GNSS back: the filter pulls the drift back over recovery_time_s (~3 time constants).
            const double decay = std::exp(-dt_ * 3.0 / std::max(cfg.recovery_time_s, dt_));
            drift *= decay;
            drift_vel.setZero();
        }
        // White noise of each INS output on top of the correlated error.
        const Eigen::Vector3d white(cfg.position_noise_m * g(white_rng),
                                    cfg.position_noise_m * g(white_rng),
                                    cfg.position_noise_m * g(white_rng));
        pos_[k] = gm_p + drift + white;
        att_[k] = gm_a;
        pos_sd_[k] = sd;
    }
}

bool NavErrorModel::InOutage(double t) const {
    for (std::size_t i = 0; i + 1 < cfg_.outages_s.size(); i += 2) {
        if (t >= cfg_.outages_s[i] && t < cfg_.outages_s[i + 1]) return true;
    }
    return false;
}

NavError NavErrorModel::At(double t) const {
    const double u = std::clamp(t / dt_, 0.0, static_cast<double>(pos_.size() - 1));
    const auto i = std::min(static_cast<std::size_t>(u), pos_.size() - 2);
    const double f = u - static_cast<double>(i);
    NavError e;
    e.position_enu_m = pos_[i] * (1 - f) + pos_[i + 1] * f;
    e.attitude_rpy_rad = att_[i] * (1 - f) + att_[i + 1] * f;
    e.position_stddev_enu_m = pos_sd_[i] * (1 - f) + pos_sd_[i + 1] * f;
    e.attitude_stddev_rpy_rad = Eigen::Vector3d(frames::DegToRad(cfg_.attitude_gm_sigma_deg),
                                                frames::DegToRad(cfg_.attitude_gm_sigma_deg),
                                                frames::DegToRad(cfg_.heading_gm_sigma_deg));
    e.gnss_available = !InOutage(t);
    const std::vector<double>& sw = cfg_.status_windows;
    for (std::size_t w = 0; w + 2 < sw.size(); w += 3) {
        if (t >= sw[w] && t < sw[w + 1]) e.ins_status = static_cast<std::uint32_t>(sw[w + 2]);
    }
    const std::vector<double>& dw = cfg_.drift_windows;
    for (std::size_t w = 0; w + 3 < dw.size(); w += 4) {
        const double a = dw[w], b = dw[w + 1];
        const Eigen::Vector3d full(dw[w + 2], dw[w + 3], 0.0);
        if (t >= a && t < b) {
            e.position_enu_m += full * ((t - a) / (b - a));
        } else if (t >= b && t < b + cfg_.recovery_time_s) {
            e.position_enu_m += full * (1.0 - (t - b) / cfg_.recovery_time_s);
        }
    }
    return e;
}

}  // namespace pitmap::sim
