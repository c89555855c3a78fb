// SPDX-License-Identifier: MIT
#include "processor/georef/mount_check.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "common/frames.hpp"

namespace pitmap::proc::georef {

namespace {

// Per ping: the floor line's slope (deg) and the vehicle's roll and pitch (deg).
struct PingSlope {
    double t_s = 0;
    double slope_deg = 0, roll_deg = 0, pitch_deg = 0;
};

using LineSums = MountLineSums;

// Each series minus its moving mean over +- half_s (the neighbours' times are sorted).
void HighPass(std::vector<PingSlope>& s, double half_s) {
    const std::size_t n = s.size();
    std::vector<PingSlope> out = s;
    std::size_t lo = 0, hi = 0;
    double sum_s = 0, sum_r = 0, sum_p = 0;
    for (std::size_t k = 0; k < n; ++k) {
        while (hi < n && s[hi].t_s <= s[k].t_s + half_s) {
            sum_s += s[hi].slope_deg;
            sum_r += s[hi].roll_deg;
            sum_p += s[hi].pitch_deg;
            ++hi;
        }
        while (s[lo].t_s < s[k].t_s - half_s) {
            sum_s -= s[lo].slope_deg;
            sum_r -= s[lo].roll_deg;
            sum_p -= s[lo].pitch_deg;
            ++lo;
        }
        const double m = static_cast<double>(hi - lo);
        out[k].slope_deg -= sum_s / m;
        out[k].roll_deg -= sum_r / m;
        out[k].pitch_deg -= sum_p / m;
    }
    s = std::move(out);
}

double Sd(const std::vector<PingSlope>& s, double PingSlope::*field) {
    double ss = 0;
    for (const auto& p : s) ss += p.*field * p.*field;
    return s.empty() ? 0.0 : std::sqrt(ss / static_cast<double>(s.size()));
}

// Each ping's floor-line sums over the soundings near the point under the sensor. The window
// is fixed on the ground, not in the fan: |u| <= depth x tan(max_angle) around that point,
// depth the mean of the beams within 5 deg of nadir. A window of beam angles would slide across
// the floor with the roll, and the floor's curvature would then turn the roll into a slope. u
// runs along the fan's horizontal direction; pings whose fan stands on end have none.
// `points`: whole pings (each ping's soundings all in it) of `geo`'s pings; added to `sums`.
void AddFloorLineSums(const GeorefResult& geo,
                      const GeorefPoints& points,
                      const MountCheckConfig& cfg,
                      std::vector<LineSums>& sums) {
    const std::size_t num_pings = geo.pings.size();
    sums.resize(num_pings);
    if (points.size() == 0) return;
    const auto [lo_it, hi_it] = std::minmax_element(points.ping.begin(), points.ping.end());
    const std::size_t lo = *lo_it;
    const std::size_t hi = std::min<std::size_t>(*hi_it + 1, num_pings);
    if (lo >= hi) return;
    const std::size_t span = hi - lo;
    std::vector<Eigen::Vector2d> fan_dir(span, Eigen::Vector2d::Zero());
    const Eigen::Matrix3d R_vs = geo.mount.R_vehicle_sonar();
    for (std::size_t k = lo; k < hi; ++k) {
        const Eigen::Vector3d y = geo.pings[k].T_world_vehicle.rotation() * R_vs.col(1);
        const Eigen::Vector2d h(y.x(), y.y());
        if (h.norm() > 0.5) fan_dir[k - lo] = h.normalized();  // fan not standing on end
    }
    std::vector<double> nadir_sum(span, 0.0);
    std::vector<int> nadir_n(span, 0);
    const double nadir = frames::DegToRad(5.0);
    for (std::size_t j = 0; j < points.size(); ++j) {
        const std::uint32_t k = points.ping[j];
        if (k >= num_pings || !(std::abs(points.angle_rad[j]) <= nadir)) continue;
        nadir_sum[k - lo] += geo.pings[k].sensor_world.z() - points.position_world[j].z();
        ++nadir_n[k - lo];
    }
    const double tan_max = std::tan(frames::DegToRad(cfg.max_angle_deg));
    const double beam_limit = frames::DegToRad(cfg.max_angle_deg + 15.0);
    for (std::size_t j = 0; j < points.size(); ++j) {
        const std::uint32_t k = points.ping[j];
        if (k >= num_pings || fan_dir[k - lo].isZero() || nadir_n[k - lo] == 0) continue;
        if (!(std::abs(points.angle_rad[j]) <= beam_limit)) continue;
        const Eigen::Vector3d d = points.position_world[j] - geo.pings[k].sensor_world;
        const double u = fan_dir[k - lo].dot(d.head<2>());
        if (std::abs(u) > tan_max * nadir_sum[k - lo] / nadir_n[k - lo]) continue;
        sums[k].Add(u, d.z());
    }
}

// The pings whose floor line is good (enough beams, spread and fit): its slope with the
// vehicle's roll and pitch, in time order.
std::vector<PingSlope> FloorSlopes(const GeorefResult& geo,
                                   const std::vector<LineSums>& sums,
                                   const MountCheckConfig& cfg) {
    std::vector<PingSlope> slopes;
    slopes.reserve(sums.size());
    for (std::size_t k = 0; k < sums.size(); ++k) {
        const LineSums& s = sums[k];
        if (s.n < cfg.min_beams) continue;
        const double n = static_cast<double>(s.n);
        const double suu = s.uu - s.u * s.u / n, suz = s.uz - s.u * s.z / n;
        const double szz = s.zz - s.z * s.z / n;
        if (!(suu > n * (cfg.min_spread_m * cfg.min_spread_m) / 12.0)) continue;
        const double b = suz / suu;
        const double rms = std::sqrt(std::max(0.0, (szz - b * suz) / n));
        if (!(rms <= cfg.max_fit_rms_m)) continue;
        const frames::Rpy a = frames::RpyFromRotationWorld(geo.pings[k].T_world_vehicle.rotation());
        slopes.push_back({static_cast<double>(geo.pings[k].utime_gps) * 1e-6,
                          frames::RadToDeg(std::atan(b)),
                          frames::RadToDeg(a.roll),
                          frames::RadToDeg(a.pitch)});
    }
    std::sort(
        slopes.begin(), slopes.end(), [](const auto& a, const auto& b) { return a.t_s < b.t_s; });
    return slopes;
}

// slope = g_r roll + g_p pitch (+ terrain, the noise) by Huber-weighted least squares (4
// passes); `cov` is the gains' covariance.
Eigen::Vector2d FitGains(const std::vector<PingSlope>& slopes, Eigen::Matrix2d& cov) {
    Eigen::Vector2d g = Eigen::Vector2d::Zero();
    cov.setZero();
    std::vector<double> w(slopes.size(), 1.0);
    for (int iter = 0; iter < 4; ++iter) {
        Eigen::Matrix2d A = Eigen::Matrix2d::Zero();
        Eigen::Vector2d y = Eigen::Vector2d::Zero();
        for (std::size_t i = 0; i < slopes.size(); ++i) {
            const Eigen::Vector2d x(slopes[i].roll_deg, slopes[i].pitch_deg);
            A += w[i] * x * x.transpose();
            y += w[i] * x * slopes[i].slope_deg;
        }
        if (A.determinant() <= 1e-12 * A.trace() * A.trace()) break;
        g = A.ldlt().solve(y);
        std::vector<double> res(slopes.size());
        for (std::size_t i = 0; i < slopes.size(); ++i) {
            res[i] = slopes[i].slope_deg - g.x() * slopes[i].roll_deg - g.y() * slopes[i].pitch_deg;
        }
        std::vector<double> a(res.size());
        for (std::size_t i = 0; i < res.size(); ++i) a[i] = std::abs(res[i]);
        std::nth_element(a.begin(), a.begin() + static_cast<std::ptrdiff_t>(a.size() / 2), a.end());
        const double sigma = std::max(1.4826 * a[a.size() / 2], 1e-6);
        double ss = 0, sw = 0;
        for (std::size_t i = 0; i < res.size(); ++i) {
            const double u = std::abs(res[i]) / (1.5 * sigma);
            w[i] = u <= 1 ? 1.0 : 1.0 / u;
            ss += w[i] * res[i] * res[i];
            sw += w[i];
        }
        // The residuals are correlated from ping to ping (terrain, the INS's own error): the
        // variance is inflated by (1 + rho) / (1 - rho), rho their lag-one correlation in time
        // order (AR(1)), as the sonar clock rate's is.
        double lag0 = 0, lag1 = 0;
        for (std::size_t i = 0; i < res.size(); ++i) {
            lag0 += w[i] * res[i] * res[i];
            if (i > 0) lag1 += std::sqrt(w[i] * w[i - 1]) * res[i] * res[i - 1];
        }
        const double rho = std::clamp(lag0 > 0 ? lag1 / lag0 : 0.0, 0.0, 0.95);
        cov = A.inverse() * (ss / std::max(sw - 2, 1.0)) * (1 + rho) / (1 - rho);
    }
    return g;
}

// The nearer of the two mistakes a connector makes, if either is near; else the mount as a
// whole.
const char* LikelyCause(double roll_gain, double pitch_gain) {
    const double ar = std::abs(roll_gain), ap = std::abs(pitch_gain);
    const double to_mirror = std::hypot(ar - 2.0, ap), to_turned = std::hypot(ar - 1.0, ap - 1.0);
    if (to_mirror < 0.8 && to_mirror <= to_turned) {
        return "the fan is mirrored (a flat floor tilts by twice the roll): the head is turned "
               "180 deg from sonar.mount.connector (forward where aft was given, or port where "
               "starboard was; or the reverse)";
    }
    if (to_turned < 0.8) {
        return "the fan is placed along the track (it keeps the roll and gains the pitch): the "
               "head is turned 90 deg from sonar.mount.connector (port or starboard where aft or "
               "forward was given; or the reverse)";
    }
    return "the soundings keep part of the vehicle's motion: sonar.mount (connector, "
           "orientation, tilt_deg) does not describe how the head is mounted";
}

}  // namespace

MountCheck CheckMountAgainstAttitude(const GeorefResult& geo, const MountCheckConfig& cfg) {
    MountCheckByBlocks check(cfg);
    check.Add(geo, geo.points);
    return check.Check(geo);
}

void MountCheckByBlocks::Add(const GeorefResult& geo, const GeorefPoints& block) {
    AddFloorLineSums(geo, block, cfg_, sums_);
}

MountCheck MountCheckByBlocks::Check(const GeorefResult& geo) const {
    const MountCheckConfig& cfg = cfg_;
    std::vector<LineSums> sums = sums_;
    sums.resize(geo.pings.size());
    MountCheck r;
    std::vector<PingSlope> slopes = FloorSlopes(geo, sums, cfg);
    r.pings = static_cast<std::int64_t>(slopes.size());
    char buf[400];
    if (r.pings < cfg.min_pings) {
        std::snprintf(buf,
                      sizeof(buf),
                      "mount check: not made: %lld pings have a floor line (%lld needed: floors "
                      "under the fan's centre, not walls)",
                      static_cast<long long>(r.pings),
                      static_cast<long long>(cfg.min_pings));
        r.message = buf;
        return r;
    }
    HighPass(slopes, 0.5 * cfg.window_s);
    r.roll_sd_deg = Sd(slopes, &PingSlope::roll_deg);
    r.pitch_sd_deg = Sd(slopes, &PingSlope::pitch_deg);
    if (std::max(r.roll_sd_deg, r.pitch_sd_deg) < cfg.min_motion_sd_deg) {
        std::snprintf(buf,
                      sizeof(buf),
                      "mount check: not made: the vehicle hardly moved (roll %.2f, pitch %.2f deg "
                      "sd at wave rate; %.2f needed)",
                      r.roll_sd_deg,
                      r.pitch_sd_deg,
                      cfg.min_motion_sd_deg);
        r.message = buf;
        return r;
    }
    Eigen::Matrix2d cov;
    const Eigen::Vector2d g = FitGains(slopes, cov);
    r.checked = true;
    r.roll_gain = g.x();
    r.pitch_gain = g.y();
    r.roll_gain_sd = std::sqrt(std::max(0.0, cov(0, 0)));
    r.pitch_gain_sd = std::sqrt(std::max(0.0, cov(1, 1)));
    // Both gains together against their covariance (a head turned 90 deg shows on both, each
    // less certain than the pair).
    const double chi2 = g.dot(cov.ldlt().solve(g));
    r.significance = std::sqrt(std::max(0.0, chi2));
    r.consistent = !(std::max(std::abs(g.x()), std::abs(g.y())) > cfg.max_gain &&
                     r.significance > cfg.min_significance);
    if (!r.consistent) r.likely_cause = LikelyCause(r.roll_gain, r.pitch_gain);
    std::snprintf(buf,
                  sizeof(buf),
                  "mount check: the floor's across-fan slope follows roll x %.2f +- %.2f and "
                  "pitch x %.2f +- %.2f (%.1f sigma) over %lld pings (motion %.2f / %.2f deg "
                  "sd)%s",
                  r.roll_gain,
                  r.roll_gain_sd,
                  r.pitch_gain,
                  r.pitch_gain_sd,
                  r.significance,
                  static_cast<long long>(r.pings),
                  r.roll_sd_deg,
                  r.pitch_sd_deg,
                  r.consistent ? ": the mount explains the soundings" : "");
    r.message = buf;
    if (!r.consistent) r.message += ": " + r.likely_cause;
    return r;
}

}  // namespace pitmap::proc::georef
