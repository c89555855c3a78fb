// SPDX-License-Identifier: MIT
#include "processor/calib/sonar_clock.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>

#include "common/frames.hpp"
#include "common/geodesy.hpp"

namespace pitmap::proc::calib {

namespace {

constexpr double kPi = 3.14159265358979323846;

double WrapDeg(double a) {
    a = std::fmod(a + 180.0, 360.0);
    if (a < 0) a += 360.0;
    return a - 180.0;
}

// The INS series as plain arrays: times in seconds since t_ref, ENU positions, unwrapped angles.
class NavTrack {
public:
    NavTrack(const georef::NavSeries& nav, std::int64_t t_ref, const Eigen::Vector3d& antenna)
        : world_(nav.samples.front().position) {
        t_.reserve(nav.samples.size());
        double yaw_prev = 0;
        for (std::size_t i = 0; i < nav.samples.size(); ++i) {
            const auto& s = nav.samples[i];
            t_.push_back(static_cast<double>(s.utime_gps - t_ref) * 1e-6);
            const Eigen::Matrix3d R =
                frames::RotationWorldFromRpy(s.roll_rad, s.pitch_rad, s.yaw_rad);
            const Eigen::Vector3d p = world_.ToEnu(s.position) + R * antenna;
            east_.push_back(p.x());
            north_.push_back(p.y());
            roll_.push_back(frames::RadToDeg(s.roll_rad));
            pitch_.push_back(frames::RadToDeg(s.pitch_rad));
            double yaw = frames::RadToDeg(s.yaw_rad);
            if (i > 0) yaw = yaw_prev + WrapDeg(yaw - yaw_prev);
            yaw_.push_back(yaw);
            yaw_prev = yaw;
        }
    }
    const LocalTangentFrame& world() const { return world_; }
    double first() const { return t_.front(); }
    double last() const { return t_.back(); }

    struct At {
        double east, north, roll, pitch, yaw;
    };
    // Linear interpolation; nullopt outside the span or across a gap over 1 s.
    std::optional<At> Interpolate(double t) const {
        if (t_.size() < 2 || t < t_.front() || t > t_.back()) return std::nullopt;
        auto it = std::upper_bound(t_.begin(), t_.end(), t);
        std::size_t i1 = static_cast<std::size_t>(it - t_.begin());
        if (i1 >= t_.size()) i1 = t_.size() - 1;
        const std::size_t i0 = i1 - 1;
        const double dt = t_[i1] - t_[i0];
        if (dt > 1.0) return std::nullopt;
        const double f = dt > 0 ? (t - t_[i0]) / dt : 0.0;
        auto lerp = [&](const std::vector<double>& v) { return v[i0] + f * (v[i1] - v[i0]); };
        return At{lerp(east_), lerp(north_), lerp(roll_), lerp(pitch_), lerp(yaw_)};
    }

private:
    LocalTangentFrame world_;
    std::vector<double> t_, east_, north_, roll_, pitch_, yaw_;
};

struct AidSample {
    double t = 0;  // ping time, seconds since t_ref, on the sonar's clock
    double east = 0, north = 0;
    double roll = 0, pitch = 0, heading = 0;
};

double Median(std::vector<double>& v) {
    if (v.empty()) return std::numeric_limits<double>::infinity();
    const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
    std::nth_element(v.begin(), mid, v.end());
    return *mid;
}

// Keeps at most n samples, evenly.
std::vector<AidSample> Thin(std::vector<AidSample> v, int n) {
    if (n <= 0 || static_cast<int>(v.size()) <= n) return v;
    std::vector<AidSample> out;
    out.reserve(static_cast<std::size_t>(n));
    for (int i = 0; i < n; ++i) {
        out.push_back(v[static_cast<std::size_t>(static_cast<double>(i) * v.size() / n)]);
    }
    return out;
}

enum class AttitudeUse { kHeading, kRollPitch };

// Score functions return +inf when too few samples fall inside the nav span.
double PositionMisfit(const std::vector<AidSample>& s,
                      const NavTrack& nav,
                      double c,
                      double min_fraction) {
    std::vector<double> d;
    d.reserve(s.size());
    for (const auto& a : s) {
        if (auto n = nav.Interpolate(a.t + c))
            d.push_back(std::hypot(a.east - n->east, a.north - n->north));
    }
    if (d.size() < std::max<std::size_t>(5, static_cast<std::size_t>(min_fraction * s.size())))
        return std::numeric_limits<double>::infinity();
    return Median(d);
}

double AttitudeMisfit(const std::vector<AidSample>& s,
                      const NavTrack& nav,
                      double c,
                      double min_fraction,
                      AttitudeUse use) {
    std::vector<double> a, b;
    a.reserve(s.size());
    b.reserve(s.size());
    double sin_sum = 0, cos_sum = 0;
    for (const auto& x : s) {
        auto n = nav.Interpolate(x.t + c);
        if (!n) continue;
        if (use == AttitudeUse::kHeading) {
            const double d = WrapDeg(x.heading - n->yaw);
            a.push_back(d);
            sin_sum += std::sin(d * kPi / 180);
            cos_sum += std::cos(d * kPi / 180);
        } else {
            a.push_back(x.roll - n->roll);
            b.push_back(x.pitch - n->pitch);
        }
    }
    if (a.size() < std::max<std::size_t>(5, static_cast<std::size_t>(min_fraction * s.size())))
        return std::numeric_limits<double>::infinity();
    double ss = 0;
    if (use == AttitudeUse::kHeading) {
        const double bias = std::atan2(sin_sum, cos_sum) * 180 / kPi;  // the mount's yaw
        for (double d : a) ss += std::pow(WrapDeg(d - bias), 2);
        return std::sqrt(ss / static_cast<double>(a.size()));
    }
    // The mean difference is the mount; what is left is timing (and sensor noise).
    auto centred_ss = [](const std::vector<double>& v) {
        double m = 0;
        for (double x : v) m += x;
        m /= static_cast<double>(v.size());
        double q = 0;
        for (double x : v) q += (x - m) * (x - m);
        return q;
    };
    ss = centred_ss(a) + centred_ss(b);
    return std::sqrt(ss / static_cast<double>(2 * a.size()));
}

struct ScanResult {
    double best_c = 0, best = std::numeric_limits<double>::infinity();
    double alias_c = 0, alias = 0;  // alias = 0: none
};

// Scans c over [lo, hi] in `step`; the best and the best local minimum far enough from it.
template <class F>
ScanResult Scan(const F& f, double lo, double hi, double step, double min_sep) {
    ScanResult r;
    const auto n = static_cast<std::size_t>(std::max(1.0, std::floor((hi - lo) / step) + 1));
    std::vector<double> cs(n), v(n);
    for (std::size_t i = 0; i < n; ++i) {
        cs[i] = lo + static_cast<double>(i) * step;
        v[i] = f(cs[i]);
        if (v[i] < r.best) {
            r.best = v[i];
            r.best_c = cs[i];
        }
    }
    double alias = std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < n; ++i) {
        if (!std::isfinite(v[i]) || std::abs(cs[i] - r.best_c) < min_sep) continue;
        const bool local = (i == 0 || v[i] <= v[i - 1]) && (i + 1 == n || v[i] <= v[i + 1]);
        if (local && v[i] < alias) {
            alias = v[i];
            r.alias_c = cs[i];
        }
    }
    r.alias = std::isfinite(alias) ? alias : 0.0;
    return r;
}

// Minimum of a parabola through (c - h, a), (c, b), (c + h, d); c when it is not convex.
double ParabolaVertex(double c, double h, double a, double b, double d) {
    const double den = a - 2 * b + d;
    if (!(den > 0) || !std::isfinite(a) || !std::isfinite(d)) return c;
    return c + 0.5 * h * (a - d) / den;
}

}  // namespace

std::string SpanText(std::int64_t first_utime, std::int64_t last_utime) {
    char s[96];
    std::snprintf(s,
                  sizeof(s),
                  "%.3f .. %.3f GPS s (%.1f s)",
                  static_cast<double>(first_utime) * 1e-6,
                  static_cast<double>(last_utime) * 1e-6,
                  static_cast<double>(last_utime - first_utime) * 1e-6);
    return s;
}

ClockEstimate EstimateSonarClock(const georef::PingSeries& pings,
                                 const georef::NavSeries& nav,
                                 const ClockSearchConfig& cfg) {
    ClockEstimate est;
    est.method = "none";
    if (pings.pings.size() < 2 || nav.samples.size() < 2) {
        est.message = "too few pings or navigation samples to find the sonar clock";
        return est;
    }
    const std::int64_t t_ref = nav.samples.front().utime_gps;
    const NavTrack track(nav, t_ref, cfg.antenna_lever_arm_m);
    const double p0 = static_cast<double>(pings.pings.front().utime_gps - t_ref) * 1e-6;
    const double p1 = static_cast<double>(pings.pings.back().utime_gps - t_ref) * 1e-6;
    // Every c that overlaps the two spans at all.
    const double lo = track.first() - p1, hi = track.last() - p0;
    const double ping_interval = (p1 - p0) / static_cast<double>(pings.pings.size() - 1);

    std::vector<AidSample> pos, att;
    bool have_heading = false, have_roll_pitch = false;
    double last_lat = std::numeric_limits<double>::quiet_NaN(), last_lon = last_lat;
    for (const auto& h : pings.pings) {
        const double t = static_cast<double>(h.utime_gps - t_ref) * 1e-6;
        if (std::isfinite(h.aid_latitude_deg) && std::isfinite(h.aid_longitude_deg) &&
            (h.aid_latitude_deg != last_lat || h.aid_longitude_deg != last_lon)) {
            // First ping that carries this fix: the fix is at most a ping interval old.
            const Eigen::Vector3d e =
                track.world().ToEnu({h.aid_latitude_deg, h.aid_longitude_deg, 0.0});
            pos.push_back({t, e.x(), e.y(), 0, 0, 0});
        }
        last_lat = h.aid_latitude_deg;
        last_lon = h.aid_longitude_deg;
        const bool rp = std::isfinite(h.aid_roll_deg) && std::isfinite(h.aid_pitch_deg);
        const bool hd = std::isfinite(h.aid_heading_deg);
        if (rp || hd) {
            att.push_back({t,
                           0,
                           0,
                           rp ? h.aid_roll_deg : 0.0,
                           rp ? h.aid_pitch_deg : 0.0,
                           hd ? h.aid_heading_deg : 0.0});
            have_roll_pitch |= rp;
            have_heading |= hd;
        }
    }
    const double step = std::max(cfg.scan_step_s, (hi - lo) / 200000.0);
    char buf[320];
    auto finish = [&](const ScanResult& coarse,
                      const auto& score,
                      double limit,
                      const char* unit,
                      double stale_s) {
        // Fine scan around the coarse minimum, then a parabola through the best three.
        const ScanResult fine = Scan(score,
                                     coarse.best_c - cfg.fine_window_s,
                                     coarse.best_c + cfg.fine_window_s,
                                     cfg.fine_step_s,
                                     1e9);
        const double h = cfg.fine_step_s;
        est.correction_s = ParabolaVertex(
            fine.best_c, h, score(fine.best_c - h), fine.best, score(fine.best_c + h));
        est.misfit = score(est.correction_s);
        if (!std::isfinite(est.misfit)) est.misfit = fine.best;
        est.alias_misfit = coarse.alias;
        est.alias_correction_s = coarse.alias_c;
        // The aids' own age is the systematic part; the statistical part is small beside it.
        est.sigma_s = std::hypot(stale_s, cfg.fine_step_s);
        // Both on the coarse grid: a refined best against an unrefined alias would hide it.
        const bool ambiguous = coarse.alias > 0 && coarse.alias < cfg.alias_ratio * coarse.best;
        const bool poor = !(est.misfit <= limit);
        est.found = !ambiguous && !poor;
        if (ambiguous) {
            std::snprintf(buf,
                          sizeof(buf),
                          "%s: ambiguous: %+.3f s (misfit %.3g %s) and %+.3f s (%.3g %s) fit "
                          "almost equally",
                          est.method.c_str(),
                          est.correction_s,
                          est.misfit,
                          unit,
                          coarse.alias_c,
                          coarse.alias,
                          unit);
        } else if (poor) {
            std::snprintf(buf,
                          sizeof(buf),
                          "%s: no offset fits: best %+.3f s leaves a misfit of %.3g %s (limit "
                          "%.3g)",
                          est.method.c_str(),
                          est.correction_s,
                          est.misfit,
                          unit,
                          limit);
        } else {
            std::snprintf(buf,
                          sizeof(buf),
                          "%s: correction %+.3f s +- %.3f s (misfit %.3g %s over %lld samples)",
                          est.method.c_str(),
                          est.correction_s,
                          est.sigma_s,
                          est.misfit,
                          unit,
                          static_cast<long long>(est.samples));
        }
        est.message = buf;
    };

    if (pos.size() >= 10) {
        est.method = "header position";
        pos = Thin(std::move(pos), cfg.max_samples);
        est.samples = static_cast<std::int64_t>(pos.size());
        const auto score = [&](double c) {
            return PositionMisfit(pos, track, c, cfg.min_overlap_fraction);
        };
        // The scan over the whole overlap range (hours for a PC clock on local time) on fewer
        // fixes; the fine scan uses all of them.
        const std::vector<AidSample> few = Thin(pos, cfg.max_coarse_samples);
        const ScanResult coarse =
            Scan([&](double c) { return PositionMisfit(few, track, c, cfg.min_overlap_fraction); },
                 lo,
                 hi,
                 step,
                 cfg.min_alias_separation_s);
        // A fix reaches the topside a serial latency (~0.1-0.2 s) after its epoch and shows in
        // the next ping: up to a ping interval later.
        finish(coarse,
               score,
               cfg.max_position_misfit_m,
               "m",
               std::hypot(ping_interval / std::sqrt(12.0), cfg.fix_latency_sigma_s));
        // The fix a ping carries is older than the ping: the match found the fix's epoch,
        // which is `age` before the ping.
        const double age = cfg.assumed_fix_latency_s + 0.5 * ping_interval;
        est.correction_s += age;
        if (est.found) {
            std::snprintf(buf,
                          sizeof(buf),
                          "%s: correction %+.3f s +- %.3f s (misfit %.3g m over %lld fixes, "
                          "their mean age of %.3f s taken off)",
                          est.method.c_str(),
                          est.correction_s,
                          est.sigma_s,
                          est.misfit,
                          static_cast<long long>(est.samples),
                          age);
            est.message = buf;
        }
        return est;
    }
    if (att.size() >= 10) {
        est.method = "header attitude";
        att = Thin(std::move(att), cfg.max_samples);
        est.samples = static_cast<std::int64_t>(att.size());
        const AttitudeUse coarse_use =
            have_heading ? AttitudeUse::kHeading : AttitudeUse::kRollPitch;
        const auto coarse_score = [&](double c) {
            return AttitudeMisfit(att, track, c, cfg.min_overlap_fraction, coarse_use);
        };
        const std::vector<AidSample> few = Thin(att, cfg.max_coarse_samples);
        const ScanResult coarse = Scan(
            [&](double c) {
                return AttitudeMisfit(few, track, c, cfg.min_overlap_fraction, coarse_use);
            },
            lo,
            hi,
            step,
            cfg.min_alias_separation_s);
        if (have_heading && have_roll_pitch) {
            // Heading placed it (and decides ambiguity: turns are unique); the roll and pitch
            // of the waves are sharper locally, so the fine scan uses them.
            const auto rp_score = [&](double c) {
                return AttitudeMisfit(
                    att, track, c, cfg.min_overlap_fraction, AttitudeUse::kRollPitch);
            };
            finish(coarse, rp_score, cfg.max_attitude_misfit_deg, "deg", 0.5 * ping_interval);
            return est;
        }
        finish(coarse, coarse_score, cfg.max_attitude_misfit_deg, "deg", 0.5 * ping_interval);
        return est;
    }
    // Nothing but the clock: assume the two recordings ran at the same time.
    est.method = "span";
    const double nav_len = track.last() - track.first();
    const double ping_len = p1 - p0;
    est.correction_s = 0.5 * (track.first() + track.last()) - 0.5 * (p0 + p1);
    est.sigma_s = std::abs(nav_len - ping_len) / (2.0 * std::sqrt(3.0));
    est.found = true;
    std::snprintf(buf,
                  sizeof(buf),
                  "span: the 83P headers carry no position or attitude; centring the sonar's "
                  "%.1f s on the navigation's %.1f s gives %+.3f s +- %.3f s",
                  ping_len,
                  nav_len,
                  est.correction_s,
                  est.sigma_s);
    est.message = buf;
    return est;
}

}  // namespace pitmap::proc::calib
