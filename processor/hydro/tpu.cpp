// SPDX-License-Identifier: MIT
#include "processor/hydro/tpu.hpp"

#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>

#include "common/frames.hpp"

namespace pitmap::proc::hydro {

namespace {

Eigen::Matrix3d Outer(const Eigen::Vector3d& j, double variance) {
    return j * j.transpose() * variance;
}

double Square(double x) {
    return x * x;
}

// World-frame angular velocity that takes R0 to R1 in dt: R1 = exp([w dt]x) R0.
Eigen::Vector3d AngularRate(const Eigen::Matrix3d& R0, const Eigen::Matrix3d& R1, double dt) {
    const Eigen::AngleAxisd aa(R1 * R0.transpose());
    return aa.axis() * (aa.angle() / dt);
}

double Median(std::vector<float> v) {
    if (v.empty()) return 0;
    const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
    std::nth_element(v.begin(), mid, v.end());
    return *mid;
}

}  // namespace

const char* ToString(TpuTerm t) {
    switch (t) {
        case TpuTerm::kRange:
            return "range";
        case TpuTerm::kBeamAngle:
            return "beam_angle";
        case TpuTerm::kSoundSpeed:
            return "sound_speed";
        case TpuTerm::kAttitude:
            return "attitude";
        case TpuTerm::kPosition:
            return "position";
        case TpuTerm::kHeave:
            return "heave";
        case TpuTerm::kLeverArm:
            return "lever_arm";
        case TpuTerm::kLatency:
            return "latency";
        case TpuTerm::kCount:
            break;
    }
    return "?";
}

PingSigma FallbackSigma(const SensorErrorModel& m) {
    PingSigma s;
    s.attitude_rpy_rad << frames::DegToRad(m.roll_pitch_sigma_deg),
        frames::DegToRad(m.roll_pitch_sigma_deg), frames::DegToRad(m.heading_sigma_deg);
    s.position_enu_m << m.position_sigma_h_m, m.position_sigma_h_m, m.position_sigma_v_m;
    return s;
}

PingSigma InsSigmaAt(const std::vector<survey::NavStdDev>& s,
                     std::int64_t utime_gps,
                     double max_age_s,
                     const PingSigma& fallback,
                     bool* from_ins) {
    if (from_ins != nullptr) *from_ins = false;
    if (s.empty()) return fallback;
    auto it = std::lower_bound(
        s.begin(), s.end(), utime_gps, [](const survey::NavStdDev& d, std::int64_t t) {
            return d.utime_gps < t;
        });
    if (it == s.end() ||
        (it != s.begin() && utime_gps - std::prev(it)->utime_gps < it->utime_gps - utime_gps)) {
        it = std::prev(it);
    }
    if (std::abs(static_cast<double>(it->utime_gps - utime_gps)) * 1e-6 > max_age_s) {
        return fallback;
    }
    if (from_ins != nullptr) *from_ins = true;
    const double deg = frames::DegToRad(1.0);
    const auto pick = [](double v, double fb) { return std::isfinite(v) && v > 0 ? v : fb; };
    PingSigma out;
    out.attitude_rpy_rad << pick(it->roll_deg * deg, fallback.attitude_rpy_rad[0]),
        pick(it->pitch_deg * deg, fallback.attitude_rpy_rad[1]),
        pick(it->yaw_deg * deg, fallback.attitude_rpy_rad[2]);
    out.position_enu_m << pick(it->east_m, fallback.position_enu_m[0]),
        pick(it->north_m, fallback.position_enu_m[1]), pick(it->up_m, fallback.position_enu_m[2]);
    return out;
}

std::vector<std::string> TpuConfig::Validate() const {
    std::vector<std::string> out = model.Validate();
    if (!(std::isfinite(clock_sigma_s) && clock_sigma_s >= 0)) {
        out.push_back("tpu: clock_sigma_s must be finite and >= 0");
    }
    if (!(sound_speed_mps >= 1300 && sound_speed_mps <= 1700)) {
        out.push_back("tpu: sound_speed_mps must be within 1300..1700");
    }
    if (!(column_swath_half_angle_deg >= 0 && column_swath_half_angle_deg <= 75)) {
        out.push_back("tpu: column_swath_half_angle_deg must be within 0..75");
    }
    if (num_threads < 0) out.push_back("tpu: num_threads must be >= 0 (0 = all cores)");
    for (const double b : boresight_sigma_rpy_deg) {
        if (!(std::isnan(b) || (std::isfinite(b) && b >= 0))) {
            out.push_back("tpu: boresight_sigma_rpy_deg must be NaN (the model's) or >= 0");
            break;
        }
    }
    return out;
}

Eigen::Matrix3d SoundingCovariance(const SoundingGeometry& g,
                                   const PingSigma& sigma,
                                   const TpuConfig& config,
                                   std::array<Eigen::Matrix3d, kNumTpuTerms>* terms) {
    const SensorErrorModel& m = config.model;
    const double c = config.sound_speed_mps;
    const double r = g.range_m, th = g.angle_rad;
    const double ct = std::cos(g.tilt_rad), st = std::sin(g.tilt_rad);
    // Ry(tilt) applied to (0, r sin th, r cos th) and to its derivative in theta.
    const auto tilt = [&](const Eigen::Vector3d& v) {
        return Eigen::Vector3d(ct * v.x() + st * v.z(), v.y(), -st * v.x() + ct * v.z());
    };
    const Eigen::Vector3d b = tilt(Eigen::Vector3d(0, r * std::sin(th), r * std::cos(th)));
    const Eigen::Vector3d db = tilt(Eigen::Vector3d(0, r * std::cos(th), -r * std::sin(th)));
    const Eigen::Matrix3d R_ws = g.R_world_vehicle * g.R_vehicle_sonar;
    const Eigen::Vector3d u = r > 0 ? Eigen::Vector3d(R_ws * b / r) : Eigen::Vector3d::UnitZ();
    const Eigen::Vector3d dp_dtheta = R_ws * db;
    const Eigen::Vector3d d = g.R_world_vehicle * g.lever_arm_m + R_ws * b;

    std::array<Eigen::Matrix3d, kNumTpuTerms> t;
    for (auto& x : t) x.setZero();
    auto& T = t;
    const auto at = [&T](TpuTerm k) -> Eigen::Matrix3d& { return T[static_cast<int>(k)]; };

    at(TpuTerm::kRange) = Outer(u, Square(m.range_sigma_m + m.range_sigma_fraction * r));
    at(TpuTerm::kBeamAngle) = Outer(dp_dtheta, Square(frames::DegToRad(m.beam_angle_sigma_deg)));
    // The column's speed moves the sounding by the refraction-error relation (sound_speed.hpp);
    // the surface sound speed steers the beam.
    const double column_sigma = std::isnan(sigma.column_speed_sigma_mps)
                                    ? m.mean_sound_speed_sigma_mps
                                    : sigma.column_speed_sigma_mps;
    const double surface_sigma = std::isnan(sigma.surface_speed_sigma_mps)
                                     ? m.surface_sound_speed_sigma_mps
                                     : sigma.surface_speed_sigma_mps;
    const Eigen::Vector3d o = R_ws * b;
    double rel2 = Square(column_sigma / c);
    Eigen::Vector3d j_column = o;  // not below the transducer: the range scaling alone
    Eigen::Vector3d j_swath = Eigen::Vector3d::Zero();
    if (o.z() < -1e-6) {
        if (config.column_relative_sigma_at) {
            const double s = config.column_relative_sigma_at(-o.z(), column_sigma / c);
            if (std::isfinite(s)) rel2 = Square(s);
        }
        // tan^2 capped at 72 deg from the vertical, beyond any beam the fan steers to.
        const double tan2 = std::min((o.x() * o.x() + o.y() * o.y()) / (o.z() * o.z()), 9.5);
        j_column = Eigen::Vector3d(2 * o.x(), 2 * o.y(), (1 - tan2) * o.z());
        if (config.column_swath_half_angle_deg > 0) {
            const double a = frames::DegToRad(config.column_swath_half_angle_deg);
            j_swath.z() = (2 * a - std::tan(a)) / a * o.z();
        }
    }
    at(TpuTerm::kSoundSpeed) = Outer(j_column, rel2) + Outer(j_swath, rel2) +
                               Outer(dp_dtheta, Square(std::tan(th) * surface_sigma / c));

    // Attitude: dR/dk = [a_k]x R for R = M Rz(yaw) Ry(pitch) Rx(roll).
    // a_pitch = M Rz(yaw) e_y = M (-sin yaw, cos yaw, 0); with R_ned = M^T R (M = M^T),
    // R_ned(1,0) = sin(yaw) cos(pitch), R_ned(0,0) = cos(yaw) cos(pitch), cos(pitch) >= 0.
    const Eigen::Matrix3d M = frames::RotationEnuFromNed();
    const Eigen::Matrix3d R_ned = M * g.R_world_vehicle;
    const double h = std::hypot(R_ned(1, 0), R_ned(0, 0));
    Eigen::Vector3d a_pitch_ned(-R_ned(1, 0) / h, R_ned(0, 0) / h, 0.0);
    if (!(h > 1e-9)) {  // pitch at +-90 deg: yaw from the full decomposition
        const frames::Rpy rpy = frames::RpyFromRotationWorld(g.R_world_vehicle);
        a_pitch_ned = Eigen::Vector3d(-std::sin(rpy.yaw), std::cos(rpy.yaw), 0.0);
    }
    const Eigen::Vector3d a_roll = g.R_world_vehicle * Eigen::Vector3d::UnitX();
    const Eigen::Vector3d a_pitch = M * a_pitch_ned;
    const Eigen::Vector3d a_yaw = M * Eigen::Vector3d::UnitZ();
    double bore2[3];
    for (int k = 0; k < 3; ++k) {
        const double cal = config.boresight_sigma_rpy_deg[static_cast<std::size_t>(k)];
        bore2[k] = Square(frames::DegToRad(std::isnan(cal) ? m.boresight_sigma_deg : cal));
    }
    at(TpuTerm::kAttitude) = Outer(a_roll.cross(d), Square(sigma.attitude_rpy_rad[0]) + bore2[0]) +
                             Outer(a_pitch.cross(d), Square(sigma.attitude_rpy_rad[1]) + bore2[1]) +
                             Outer(a_yaw.cross(d), Square(sigma.attitude_rpy_rad[2]) + bore2[2]);

    Eigen::Matrix3d pos = Eigen::Matrix3d::Identity() * Square(m.position_noise_m);
    for (int i = 0; i < 3; ++i) pos(i, i) += Square(sigma.position_enu_m[i]);
    at(TpuTerm::kPosition) = pos;
    at(TpuTerm::kHeave) = Outer(Eigen::Vector3d::UnitZ(), Square(m.heave_sigma_m));
    at(TpuTerm::kLeverArm) = Eigen::Matrix3d::Identity() * Square(m.lever_arm_sigma_m);
    at(TpuTerm::kLatency) = Outer(g.velocity_mps + g.angular_rate_radps.cross(d),
                                  Square(m.latency_sigma_s) + Square(config.clock_sigma_s));

    Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
    for (const auto& x : t) C += x;
    if (terms != nullptr) *terms = t;
    return C;
}

TpuByBlocks::TpuByBlocks(const std::vector<georef::GeorefPing>& pings,
                         const survey::SonarMount& mount,
                         const std::vector<PingSigma>& ping_sigma,
                         const TpuConfig& config,
                         std::size_t soundings)
    : pings_(pings),
      ping_sigma_(ping_sigma),
      config_(config),
      lever_arm_m_(mount.lever_arm_m),
      R_vehicle_sonar_(mount.R_vehicle_sonar()) {
    const std::size_t n = soundings;
    const std::size_t np = pings.size();
    out_.thu_95_m.assign(n, 0.0f);
    out_.tvu_95_m.assign(n, 0.0f);
    out_.sigma_v_common_m.assign(n, 0.0f);
    out_.sigma_h_common_m.assign(n, 0.0f);
    share_.assign((n + kShareChunk - 1) / kShareChunk, std::array<double, kNumTpuTerms>{});
    if (ping_sigma.size() != np) {
        out_.message = "tpu: " + std::to_string(ping_sigma.size()) + " ping sigmas for " +
                       std::to_string(np) + " pings";
        return;
    }
    // Velocity and angular rate at each ping from its neighbours (central differences).
    velocity_.assign(np, Eigen::Vector3d::Zero());
    rate_.assign(np, Eigen::Vector3d::Zero());
    for (std::size_t k = 0; k < np; ++k) {
        const std::size_t a = k > 0 ? k - 1 : k, b = k + 1 < np ? k + 1 : k;
        const double dt = static_cast<double>(pings[b].utime_gps - pings[a].utime_gps) * 1e-6;
        if (a == b || !(dt > 0) || dt > 2.0) continue;
        velocity_[k] =
            (pings[b].T_world_vehicle.translation() - pings[a].T_world_vehicle.translation()) / dt;
        rate_[k] =
            AngularRate(pings[a].T_world_vehicle.linear(), pings[b].T_world_vehicle.linear(), dt);
    }
}

void TpuByBlocks::Add(const georef::GeorefPoints& points, std::size_t first) {
    if (!out_.message.empty()) return;  // the ping sigmas did not match
    const std::size_t n = out_.tvu_95_m.size();
    const std::size_t end_all = std::min(n, first + points.size());
    if (first != next_ || first >= end_all) return;
    next_ = end_all;
    std::unique_ptr<tbb::global_control> limit;
    if (config_.num_threads > 0) {
        limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                      config_.num_threads);
    }
    // The chunks of kShareChunk soundings this block reaches, each summed in sounding order from
    // what an earlier block left in it: the same additions as over the whole view.
    const std::size_t c0 = first / kShareChunk, c1 = (end_all - 1) / kShareChunk;
    tbb::parallel_for(c0, c1 + 1, [&](std::size_t chunk) {
        std::array<double, kNumTpuTerms> s = share_[chunk];
        std::array<Eigen::Matrix3d, kNumTpuTerms> terms;
        const std::size_t begin = std::max(first, chunk * kShareChunk);
        const std::size_t end = std::min(end_all, (chunk + 1) * kShareChunk);
        for (std::size_t j = begin; j < end; ++j) {
            const std::size_t b = j - first;  // in the block
            const std::uint32_t k = points.ping[b];
            const georef::GeorefPing& ping = pings_[k];
            SoundingGeometry g;
            g.R_world_vehicle = ping.T_world_vehicle.linear();
            g.R_vehicle_sonar = R_vehicle_sonar_;
            g.lever_arm_m = lever_arm_m_;
            g.range_m = points.range_m[b];
            g.angle_rad = points.angle_rad[b];
            g.tilt_rad = ping.profile_tilt_rad;
            g.velocity_mps = velocity_[k];
            g.angular_rate_radps = rate_[k];
            const Eigen::Matrix3d C = SoundingCovariance(g, ping_sigma_[k], config_, &terms);
            out_.tvu_95_m[j] = static_cast<float>(kTvu95 * std::sqrt(std::max(C(2, 2), 0.0)));
            out_.thu_95_m[j] =
                static_cast<float>(kThu95 * std::sqrt(std::max((C(0, 0) + C(1, 1)) / 2.0, 0.0)));
            const double independent = terms[static_cast<int>(TpuTerm::kRange)](2, 2) +
                                       terms[static_cast<int>(TpuTerm::kBeamAngle)](2, 2) +
                                       Square(config_.model.position_noise_m);
            out_.sigma_v_common_m[j] =
                static_cast<float>(std::sqrt(std::max(C(2, 2) - independent, 0.0)));
            const auto h2 = [](const Eigen::Matrix3d& m) { return (m(0, 0) + m(1, 1)) / 2.0; };
            const double independent_h = h2(terms[static_cast<int>(TpuTerm::kRange)]) +
                                         h2(terms[static_cast<int>(TpuTerm::kBeamAngle)]) +
                                         Square(config_.model.position_noise_m);
            out_.sigma_h_common_m[j] =
                static_cast<float>(std::sqrt(std::max(h2(C) - independent_h, 0.0)));
            if (C(2, 2) > 0) {
                for (int t = 0; t < kNumTpuTerms; ++t) s[t] += terms[t](2, 2) / C(2, 2);
            }
        }
        share_[chunk] = s;
    });
}

TpuResult TpuByBlocks::Finish() {
    TpuResult out = std::move(out_);
    if (!out.message.empty()) return out;
    const std::size_t n = out.tvu_95_m.size();
    for (const auto& s : share_) {
        for (int t = 0; t < kNumTpuTerms; ++t) out.tvu_variance_share[t] += s[t];
    }
    if (n > 0) {
        for (double& s : out.tvu_variance_share) s /= static_cast<double>(n);
    }
    out.median_tvu_95_m = Median(out.tvu_95_m);
    out.median_thu_95_m = Median(out.thu_95_m);
    char buf[160];
    std::snprintf(buf,
                  sizeof buf,
                  "%zu soundings: median TVU %.3f m, THU %.3f m (95 %%)",
                  n,
                  out.median_tvu_95_m,
                  out.median_thu_95_m);
    out.message = buf;
    return out;
}

TpuResult ComputeTpu(const georef::GeorefResult& geo,
                     const survey::SonarMount& mount,
                     const std::vector<PingSigma>& ping_sigma,
                     const TpuConfig& config) {
    TpuByBlocks tpu(geo.pings, mount, ping_sigma, config, geo.points.size());
    tpu.Add(geo.points, 0);
    return tpu.Finish();
}

}  // namespace pitmap::proc::hydro
