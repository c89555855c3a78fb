// SPDX-License-Identifier: MIT
#include "processor/calib/ins_slow_error.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <optional>

#include "common/frames.hpp"
#include "common/geodesy.hpp"

namespace pitmap::proc::calib {

namespace {

constexpr double kChi2OneMedian = 0.4549;  // median of a chi-square with 1 degree of freedom

double MedianOf(std::vector<double> v) {
    if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
    const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
    std::nth_element(v.begin(), mid, v.end());
    return *mid;
}

std::string Cm(double m) {
    char b[32];
    std::snprintf(b, sizeof b, "%.2f cm", 100.0 * m);
    return b;
}

// The INS antenna track in a local frame, interpolated linearly (nullopt across a gap over 1 s).
class AntennaTrack {
public:
    AntennaTrack(const survey::NavSeries& nav, const Eigen::Vector3d& lever)
        : world_(nav.samples.front().position) {
        double yaw_prev = 0;
        for (std::size_t i = 0; i < nav.samples.size(); ++i) {
            const survey::NavSample& s = nav.samples[i];
            const Eigen::Matrix3d R =
                frames::RotationWorldFromRpy(s.roll_rad, s.pitch_rad, s.yaw_rad);
            const Eigen::Vector3d p = world_.ToEnu(s.position) + R * lever;
            utime_.push_back(s.utime_gps);
            east_.push_back(p.x());
            north_.push_back(p.y());
            height_.push_back(s.position.height_m + (R * lever).z());
            double yaw = s.yaw_rad;
            if (i > 0) yaw = yaw_prev + std::remainder(yaw - yaw_prev, 2.0 * frames::kPi);
            yaw_.push_back(yaw);
            yaw_prev = yaw;
        }
    }
    const LocalTangentFrame& world() const { return world_; }
    struct At {
        double east, north, height, yaw;
    };
    std::optional<At> Interpolate(std::int64_t t) const {
        if (utime_.size() < 2 || t < utime_.front() || t > utime_.back()) return std::nullopt;
        auto it = std::upper_bound(utime_.begin(), utime_.end(), t);
        std::size_t i1 = static_cast<std::size_t>(it - utime_.begin());
        if (i1 >= utime_.size()) i1 = utime_.size() - 1;
        const std::size_t i0 = i1 - 1;
        const double dt = static_cast<double>(utime_[i1] - utime_[i0]) * 1e-6;
        if (!(dt <= 1.0)) return std::nullopt;
        const double f = dt > 0 ? static_cast<double>(t - utime_[i0]) * 1e-6 / dt : 0.0;
        const auto lerp = [&](const std::vector<double>& v) { return v[i0] + f * (v[i1] - v[i0]); };
        return At{lerp(east_), lerp(north_), lerp(height_), lerp(yaw_)};
    }

private:
    LocalTangentFrame world_;
    std::vector<std::int64_t> utime_;
    std::vector<double> east_, north_, height_, yaw_;
};

// Per-axis horizontal sigma of a stddev record; NaN when not reported.
double HorizontalSigma(const survey::NavStdDev& s) {
    const double e = s.east_m, n = s.north_m;
    if (!(e > 0) || !(n > 0)) return std::numeric_limits<double>::quiet_NaN();
    return std::sqrt(0.5 * (e * e + n * n));
}

}  // namespace

std::vector<std::string> InsSlowErrorConfig::Validate() const {
    std::vector<std::string> p;
    if (!antenna_lever_arm_m.allFinite()) p.push_back("antenna_lever_arm_m must be finite");
    if (!(good_sigma_ratio >= 1)) p.push_back("good_sigma_ratio must be >= 1");
    if (!(recovery_s >= 0)) p.push_back("recovery_s must be >= 0");
    if (!(min_speed_mps > 0)) p.push_back("min_speed_mps must be > 0");
    if (!(max_fix_age_s >= 0)) p.push_back("max_fix_age_s must be >= 0");
    if (!(max_turn_rate_deg_s > 0)) p.push_back("max_turn_rate_deg_s must be > 0");
    if (!(min_lag_s > 0) || !(max_lag_s > min_lag_s))
        p.push_back("min_lag_s must be > 0 and max_lag_s > min_lag_s");
    if (!(max_course_change_deg > 0)) p.push_back("max_course_change_deg must be > 0");
    if (!(outlier_sigmas > 1)) p.push_back("outlier_sigmas must be > 1");
    if (min_fixes < 2) p.push_back("min_fixes must be >= 2");
    if (min_products < 1) p.push_back("min_products must be >= 1");
    return p;
}

InsSlowError SlowErrorFromInnovations(const std::vector<AcrossInnovation>& a,
                                      const InsSlowErrorConfig& cfg) {
    InsSlowError r;
    if (a.size() < cfg.min_fixes) {
        r.message = "not estimated: " + std::to_string(a.size()) + " usable GNSS fixes (need " +
                    std::to_string(cfg.min_fixes) + ")";
        return r;
    }
    // Outliers (a fix from another antenna, a glitch) against a robust scale of the whole.
    std::vector<double> sq;
    sq.reserve(a.size());
    for (const AcrossInnovation& x : a) sq.push_back(x.across_m * x.across_m);
    const double scale = std::sqrt(MedianOf(sq) / kChi2OneMedian);
    const double limit = cfg.outlier_sigmas * scale;
    std::vector<char> keep(a.size(), 1);
    double sum2 = 0;
    for (std::size_t i = 0; i < a.size(); ++i) {
        if (std::abs(a[i].across_m) > limit) {
            keep[i] = 0;
            ++r.fixes_dropped;
            continue;
        }
        sum2 += a[i].across_m * a[i].across_m;
        ++r.fixes;
    }
    // Products of two fixes of one straight stretch min_lag_s..max_lag_s apart: the fixes'
    // own noise and the antenna's wave motion are uncorrelated at those lags, the slow error
    // is not (exp(-lag / tau) > 0.85 for a minute's correlation time).
    const double max_turn = frames::DegToRad(cfg.max_course_change_deg);
    double sum_prod = 0;
    for (std::size_t i = 0; i < a.size(); ++i) {
        if (keep[i] == 0) continue;
        for (std::size_t j = i + 1; j < a.size() && a[j].t_s - a[i].t_s <= cfg.max_lag_s; ++j) {
            if (keep[j] == 0 || a[j].t_s - a[i].t_s < cfg.min_lag_s) continue;
            if (!(std::abs(std::remainder(a[j].course_rad - a[i].course_rad, 2.0 * frames::kPi)) <=
                  max_turn))
                continue;
            sum_prod += a[i].across_m * a[j].across_m;
            ++r.differences;
        }
    }
    if (r.fixes < cfg.min_fixes || r.differences < cfg.min_products) {
        r.message = "not estimated: " + std::to_string(r.fixes) + " usable GNSS fixes, " +
                    std::to_string(r.differences) + " pairs of one stretch (need " +
                    std::to_string(cfg.min_fixes) + ", " + std::to_string(cfg.min_products) + ")";
        return r;
    }
    const double mean2 = sum2 / static_cast<double>(r.fixes);
    const double slow2 = std::clamp(sum_prod / static_cast<double>(r.differences), 0.0, mean2);
    r.rms_m = std::sqrt(mean2);
    r.slow_sigma_m = std::sqrt(slow2);
    r.white_sigma_m = std::sqrt(mean2 - slow2);
    r.estimated = true;
    r.message = "INS slow error " + Cm(r.slow_sigma_m) + " per axis from " +
                std::to_string(r.fixes) + " GNSS fixes across the track (RMS " + Cm(r.rms_m) +
                ", the fixes' fast part " + Cm(r.white_sigma_m) + ")";
    return r;
}

std::vector<AcrossInnovation> HeaderFixInnovations(const survey::PingSeries& pings,
                                                   const survey::NavSeries& nav,
                                                   const InsSlowErrorConfig& cfg,
                                                   double* reported_sigma_m) {
    std::vector<AcrossInnovation> out;
    if (reported_sigma_m != nullptr) *reported_sigma_m = std::numeric_limits<double>::quiet_NaN();
    if (nav.samples.size() < 2 || nav.stddevs.empty()) return out;
    // The INS's smallest reported horizontal sigma, and the times it reported more than
    // good_sigma_ratio times that (an outage, a recovery).
    double smallest = std::numeric_limits<double>::infinity();
    for (const survey::NavStdDev& s : nav.stddevs) {
        const double h = HorizontalSigma(s);
        if (std::isfinite(h)) smallest = std::min(smallest, h);
    }
    if (!std::isfinite(smallest)) return out;
    if (reported_sigma_m != nullptr) *reported_sigma_m = smallest;
    std::vector<std::int64_t> bad;  // times of the stddev records above the ratio
    for (const survey::NavStdDev& s : nav.stddevs) {
        const double h = HorizontalSigma(s);
        if (!(h <= cfg.good_sigma_ratio * smallest)) bad.push_back(s.utime_gps);
    }
    const auto recovery_us = static_cast<std::int64_t>(cfg.recovery_s * 1e6);
    // Good: the nearest record before and after are good, and no bad record within
    // recovery_s before (or a record interval after).
    const auto good_at = [&](std::int64_t t) {
        auto it = std::lower_bound(bad.begin(), bad.end(), t - recovery_us);
        if (it != bad.end() && *it <= t + 2'000'000) return false;
        return t >= nav.stddevs.front().utime_gps && t <= nav.stddevs.back().utime_gps;
    };
    const AntennaTrack track(nav, cfg.antenna_lever_arm_m);
    constexpr std::int64_t kHalfStepUs = 500'000;
    const double max_turn_rad_s = frames::DegToRad(cfg.max_turn_rate_deg_s);
    // The usable fixes: fresh, GNSS good, moving straight.
    struct Fix {
        std::int64_t t;
        Eigen::Vector3d enu;
        Eigen::Vector2d v;
    };
    std::vector<Fix> fixes;
    double last_lat = std::numeric_limits<double>::quiet_NaN(), last_lon = last_lat;
    for (const survey::PingHeader& h : pings.pings) {
        const bool fresh = std::isfinite(h.aid_latitude_deg) &&
                           std::isfinite(h.aid_longitude_deg) &&
                           (h.aid_latitude_deg != last_lat || h.aid_longitude_deg != last_lon);
        last_lat = h.aid_latitude_deg;
        last_lon = h.aid_longitude_deg;
        if (!fresh || !good_at(h.utime_gps)) continue;
        const auto at = track.Interpolate(h.utime_gps);
        const auto a0 = track.Interpolate(h.utime_gps - kHalfStepUs);
        const auto a1 = track.Interpolate(h.utime_gps + kHalfStepUs);
        if (!at || !a0 || !a1) continue;
        const Eigen::Vector2d v(a1->east - a0->east, a1->north - a0->north);  // per second
        if (!(v.norm() >= cfg.min_speed_mps)) continue;
        if (!(std::abs(a1->yaw - a0->yaw) <= max_turn_rad_s)) continue;
        // The header has no height: the fix is taken at the antenna's, else the tangent plane
        // shrinks it towards the origin by height / earth radius (6 mm at 100 m for 400 m).
        fixes.push_back({h.utime_gps,
                         track.world().ToEnu({h.aid_latitude_deg, h.aid_longitude_deg, at->height}),
                         v});
    }
    // The fixes' age (serial latency and the ping phase): the one that puts them where the INS
    // antenna was along the track (the median squared along-track innovation over a scan).
    // Comparing at the fix's own epoch also takes the antenna's wave motion over the age out.
    const auto along_cost = [&](double age_s) {
        std::vector<double> sq;
        sq.reserve(fixes.size());
        const auto age_us = static_cast<std::int64_t>(std::llround(age_s * 1e6));
        for (const Fix& f : fixes) {
            const auto at = track.Interpolate(f.t - age_us);
            if (!at) continue;
            const double along =
                f.v.normalized().dot(Eigen::Vector2d(at->east - f.enu.x(), at->north - f.enu.y()));
            sq.push_back(along * along);
        }
        return sq.empty() ? std::numeric_limits<double>::infinity() : MedianOf(std::move(sq));
    };
    double age = 0, best = std::numeric_limits<double>::infinity();
    for (double a = 0; a <= cfg.max_fix_age_s + 1e-9; a += 0.01) {
        const double c = along_cost(a);
        if (c < best) {
            best = c;
            age = a;
        }
    }
    const auto age_us = static_cast<std::int64_t>(std::llround(age * 1e6));
    for (const Fix& f : fixes) {
        const auto at = track.Interpolate(f.t - age_us);
        if (!at) continue;
        const Eigen::Vector2d u = Eigen::Vector2d(-f.v.y(), f.v.x()).normalized();
        const Eigen::Vector2d d(at->east - f.enu.x(), at->north - f.enu.y());
        out.push_back({static_cast<double>(f.t - nav.samples.front().utime_gps) * 1e-6,
                       u.dot(d),
                       std::atan2(f.v.x(), f.v.y())});
    }
    return out;
}

InsSlowError EstimateInsSlowError(const survey::PingSeries& pings,
                                  const survey::NavSeries& nav,
                                  const InsSlowErrorConfig& cfg) {
    const std::vector<std::string> problems = cfg.Validate();
    if (!problems.empty()) {
        InsSlowError r;
        r.message = "not estimated: invalid config: " + problems.front();
        return r;
    }
    double reported = std::numeric_limits<double>::quiet_NaN();
    const std::vector<AcrossInnovation> a = HeaderFixInnovations(pings, nav, cfg, &reported);
    InsSlowError r = SlowErrorFromInnovations(a, cfg);
    r.reported_sigma_m = reported;
    if (!std::isfinite(reported)) {
        r.estimated = false;
        r.message = "not estimated: the INS reports no horizontal standard deviation";
    }
    return r;
}

}  // namespace pitmap::proc::calib
