// SPDX-License-Identifier: MIT
#include "tools/sim/nav_errors.hpp"

#include <algorithm>
#include <cmath>
#include <random>

#include "common/frames.hpp"

namespace pitmap::sim {

NavErrorModel::NavErrorModel(const NavErrorConfig& cfg, double duration_s, std::uint64_t seed)
    : cfg_(cfg), seed_(seed) {
    n_ = static_cast<std::size_t>(std::ceil(std::max(duration_s, 0.0) / dt_)) + 2;
    // First-order Gauss-Markov: x' = phi x + sigma sqrt(1 - phi^2) w keeps variance sigma^2.
    phi_p_ = std::exp(-dt_ / cfg.position_gm_tau_s);
    phi_a_ = std::exp(-dt_ / cfg.attitude_gm_tau_s);
    q_p_ = std::sqrt(1 - phi_p_ * phi_p_);
    q_a_ = std::sqrt(1 - phi_a_ * phi_a_);
    sig_p_ =
        Eigen::Vector3d(cfg.position_gm_sigma_m, cfg.position_gm_sigma_m, cfg.height_gm_sigma_m);
    sig_a_ = Eigen::Vector3d(frames::DegToRad(cfg.attitude_gm_sigma_deg),
                             frames::DegToRad(cfg.attitude_gm_sigma_deg),
                             frames::DegToRad(cfg.heading_gm_sigma_deg));
    std::lock_guard lock(mu_);
    Restart();
}

void NavErrorModel::Restart() const {
    gen_.rng.seed(seed_ ^ 0xA11E5ull);
    gen_.white_rng.seed(seed_ ^ 0x3A17Eull);  // own stream: white noise does not shift the walks
    // One distribution for both engines, kept across steps, as the process was defined: it
    // caches its second variate, so the sequence depends on it (and is the same on a restart).
    gen_.g = std::normal_distribution<double>(0.0, 1.0);
    std::normal_distribution<double>& g = gen_.g;
    gen_.gm_p = Eigen::Vector3d(
        sig_p_.x() * g(gen_.rng), sig_p_.y() * g(gen_.rng), sig_p_.z() * g(gen_.rng));
    gen_.gm_a = Eigen::Vector3d(
        sig_a_.x() * g(gen_.rng), sig_a_.y() * g(gen_.rng), sig_a_.z() * g(gen_.rng));
    gen_.drift.setZero();      // dead-reckoning position error
    gen_.drift_vel.setZero();  // its rate
    gen_.outage_start = -1;
    gen_.next_k = 0;
    window_.clear();
    window_k0_ = 0;
}

NavErrorModel::Sample NavErrorModel::Step() const {
    Generator& s = gen_;
    std::normal_distribution<double>& g = s.g;
    const double t = static_cast<double>(s.next_k) * dt_;
    const Eigen::Vector3d rw(1.0, 1.0, cfg_.outage_vertical_fraction);
    for (int i = 0; i < 3; ++i) {
        s.gm_p[i] = phi_p_ * s.gm_p[i] + sig_p_[i] * q_p_ * g(s.rng);
        s.gm_a[i] = phi_a_ * s.gm_a[i] + sig_a_[i] * q_a_ * g(s.rng);
    }
    Eigen::Vector3d sd = sig_p_;
    if (InOutage(t)) {
        if (s.outage_start < 0) s.outage_start = t;
        for (int i = 0; i < 3; ++i) {
            s.drift_vel[i] +=
                rw[i] * cfg_.outage_velocity_random_walk_mps_per_sqrt_s * std::sqrt(dt_) * g(s.rng);
        }
        s.drift += s.drift_vel * dt_;
        // Integrated random walk: sigma(t) = q t^1.5 / sqrt(3); the INS reports it grows.
        const double te = t - s.outage_start;
        const double grow =
            cfg_.outage_velocity_random_walk_mps_per_sqrt_s * std::pow(te, 1.5) / std::sqrt(3.0);
        sd = (sig_p_.array().square() + (rw * grow).array().square()).sqrt();
    } else {
        s.outage_start = -1;
        // GNSS back: the filter pulls the drift back over recovery_time_s (~3 time constants).
        const double decay = std::exp(-dt_ * 3.0 / std::max(cfg_.recovery_time_s, dt_));
        s.drift *= decay;
        s.drift_vel.setZero();
    }
    // White noise of each INS output on top of the correlated error.
    const Eigen::Vector3d white(cfg_.position_noise_m * g(s.white_rng),
                                cfg_.position_noise_m * g(s.white_rng),
                                cfg_.position_noise_m * g(s.white_rng));
    ++s.next_k;
    return {s.gm_p + s.drift + white, s.gm_a, sd};
}

const NavErrorModel::Sample& NavErrorModel::SampleAt(std::size_t k) const {
    if (k < window_k0_) Restart();
    while (k >= window_k0_ + window_.size()) {
        if (window_.size() >= 2 * kChunkSteps) {
            window_.erase(window_.begin(), window_.begin() + kChunkSteps);
            window_k0_ += kChunkSteps;
        }
        window_.push_back(Step());
    }
    return window_[k - window_k0_];
}

bool NavErrorModel::InOutage(double t) const {
    for (std::size_t i = 0; i + 1 < cfg_.outages_s.size(); i += 2) {
        if (t >= cfg_.outages_s[i] && t < cfg_.outages_s[i + 1]) return true;
    }
    return false;
}

NavError NavErrorModel::At(double t) const {
    const double u = std::clamp(t / dt_, 0.0, static_cast<double>(n_ - 1));
    const auto i = std::min(static_cast<std::size_t>(u), n_ - 2);
    const double f = u - static_cast<double>(i);
    NavError e;
    {
        std::lock_guard lock(mu_);
        const Sample a = SampleAt(i);
        const Sample& b = SampleAt(i + 1);
        e.position_enu_m = a.pos * (1 - f) + b.pos * f;
        e.attitude_rpy_rad = a.att * (1 - f) + b.att * f;
        e.position_stddev_enu_m = a.pos_sd * (1 - f) + b.pos_sd * f;
    }
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
