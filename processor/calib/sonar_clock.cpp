// SPDX-License-Identifier: MIT
#include "processor/calib/sonar_clock.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
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
    NavTrack(const survey::NavSeries& nav, std::int64_t t_ref, const Eigen::Vector3d& antenna)
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

// The head's roll and pitch (deg) the INS predicts at t: its attitude composed with the mount.
std::optional<Eigen::Vector2d> HeadRollPitch(const NavTrack& nav,
                                             double t,
                                             const Eigen::Matrix3d& R_vs,
                                             bool identity_mount) {
    const auto n = nav.Interpolate(t);
    if (!n) return std::nullopt;
    if (identity_mount) return Eigen::Vector2d(n->roll, n->pitch);
    const Eigen::Matrix3d R =
        frames::RotationWorldFromRpy(
            frames::DegToRad(n->roll), frames::DegToRad(n->pitch), frames::DegToRad(n->yaw)) *
        R_vs;
    const frames::Rpy rpy = frames::RpyFromRotationWorld(R);
    return Eigen::Vector2d(frames::RadToDeg(rpy.roll), frames::RadToDeg(rpy.pitch));
}

// A ping whose header carries the head's own attitude at the ping.
struct HeadSample {
    double t;              // seconds since t_ref on the pings' clock
    Eigen::Vector2d head;  // roll, pitch, deg
};

std::vector<HeadSample> HeadSamples(const survey::PingSeries& pings, std::int64_t t_ref) {
    std::vector<HeadSample> all;
    for (const auto& h : pings.pings) {
        if (!h.aid_attitude_at_ping || !std::isfinite(h.aid_roll_deg) ||
            !std::isfinite(h.aid_pitch_deg))
            continue;
        all.push_back({static_cast<double>(h.utime_gps - t_ref) * 1e-6,
                       Eigen::Vector2d(h.aid_roll_deg, h.aid_pitch_deg)});
    }
    return all;
}

// At most n of the samples, evenly.
std::vector<HeadSample> ThinHeadSamples(std::vector<HeadSample> all, std::int64_t n_max) {
    if (static_cast<std::int64_t>(all.size()) <= n_max) return all;
    std::vector<HeadSample> S;
    const auto n = static_cast<std::size_t>(n_max);
    for (std::size_t i = 0; i < n; ++i) S.push_back(all[i * all.size() / n]);
    return S;
}

// The head's roll and pitch the INS predicts (HeadRollPitch), and measured minus predicted.
class HeadModel {
public:
    HeadModel(const survey::NavSeries& nav, std::int64_t t_ref, const Eigen::Matrix3d& R_vs)
        : track_(nav, t_ref, Eigen::Vector3d::Zero()),
          R_vs_(R_vs),
          identity_(R_vs.isIdentity(1e-12)) {}
    std::optional<Eigen::Vector2d> At(double t) const {
        return HeadRollPitch(track_, t, R_vs_, identity_);
    }
    static Eigen::Vector2d Diff(const Eigen::Vector2d& measured, const Eigen::Vector2d& predicted) {
        return Eigen::Vector2d(WrapDeg(measured.x() - predicted.x()),
                               WrapDeg(measured.y() - predicted.y()));
    }

private:
    NavTrack track_;
    Eigen::Matrix3d R_vs_;
    bool identity_;
};

// The offset d at rate 0: the de-biased RMS over a scan of +- scan_s (waves of seconds: a step
// of 10 ms is fine). Returns (d, its variance); the variance is +inf when no offset puts half
// the samples inside the navigation.
std::pair<double, double> ScanOffset(const std::vector<HeadSample>& S,
                                     const HeadModel& head,
                                     const ClockRateConfig& cfg) {
    double best_d = 0, best = std::numeric_limits<double>::infinity();
    const int n_scan = static_cast<int>(std::floor(cfg.scan_s / cfg.scan_step_s));
    for (int i = -n_scan; i <= n_scan; ++i) {
        const double d = i * cfg.scan_step_s;
        Eigen::Vector2d sum = Eigen::Vector2d::Zero(), sq = Eigen::Vector2d::Zero();
        std::size_t n = 0;
        for (const auto& x : S) {
            const auto p = head.At(x.t + d);
            if (!p) continue;
            const Eigen::Vector2d r = HeadModel::Diff(x.head, *p);
            sum += r;
            sq += r.cwiseProduct(r);
            ++n;
        }
        if (n < S.size() / 2) continue;
        const Eigen::Vector2d mean = sum / static_cast<double>(n);
        const double v = (sq / static_cast<double>(n) - mean.cwiseProduct(mean)).sum();
        if (v < best) {
            best = v;
            best_d = d;
        }
    }
    return {best_d, best};
}

// The mean roll and pitch difference at offset d: the biases' start values.
Eigen::Vector2d MeanDifference(const std::vector<HeadSample>& S, const HeadModel& head, double d) {
    Eigen::Vector2d sum = Eigen::Vector2d::Zero();
    std::size_t n = 0;
    for (const auto& s : S) {
        if (const auto p = head.At(s.t + d)) {
            sum += HeadModel::Diff(s.head, *p);
            ++n;
        }
    }
    return sum / static_cast<double>(std::max<std::size_t>(n, 1));
}

// The clock model's fit: x = [d (s), rate (ppm), bias roll, bias pitch (deg)]; a ping at t is at
// t + d + rate 1e-6 (t - t_mid) on the INS's clock.
struct RateFit {
    Eigen::Vector4d x;
    Eigen::Matrix4d info = Eigen::Matrix4d::Zero();  // data and prior, 1 / sigma^2 units
    std::vector<Eigen::Vector2d> res;                // residuals at x, per sample
    std::vector<char> valid;                         // the sample's time is inside the INS
    std::size_t n_res = 0;                           // residuals in info
    double ss = 0;                                   // unweighted residual squares (roll and pitch)
};

// The residuals' robust scale, and their variance inflated for their correlation from ping to
// ping (AR(1): (1 + rho) / (1 - rho)). Zero scale: too few residuals.
struct Noise {
    double scale = 0, variance = 0;
};

// The residuals at fit.x (res, valid, ss) and their noise.
Noise Residuals(const std::vector<HeadSample>& S,
                const HeadModel& head,
                double t_mid,
                const ClockRateConfig& cfg,
                RateFit& fit) {
    const Eigen::Vector4d& x = fit.x;
    std::vector<double> abs_r;
    double lag0 = 0, lag1 = 0;
    fit.ss = 0;
    for (std::size_t i = 0; i < S.size(); ++i) {
        const double tau = x[0] + x[1] * 1e-6 * (S[i].t - t_mid);
        const auto p = head.At(S[i].t + tau);
        fit.valid[i] = p.has_value();
        if (!p) continue;
        fit.res[i] = HeadModel::Diff(S[i].head, *p) - x.tail<2>();
        abs_r.push_back(std::abs(fit.res[i].x()));
        abs_r.push_back(std::abs(fit.res[i].y()));
        fit.ss += fit.res[i].squaredNorm();
        lag0 += fit.res[i].squaredNorm();
        if (i > 0 && fit.valid[i - 1]) lag1 += fit.res[i].dot(fit.res[i - 1]);
    }
    Noise n;
    if (abs_r.size() < 8) return n;
    const double robust_sigma = 1.4826 * Median(abs_r);
    n.scale = std::max(cfg.cauchy_scale_deg, 2.5 * robust_sigma);
    const double rho = std::clamp(lag0 > 0 ? lag1 / lag0 : 0.0, 0.0, 0.95);
    n.variance = std::max(robust_sigma * robust_sigma, 1e-12) * (1 + rho) / (1 - rho);
    return n;
}

// The data's normal equations at fit.x (Cauchy weights) into fit.info and fit.n_res; returns
// the gradient. The attitude rate by central differences over +- 0.05 s.
Eigen::Vector4d NormalEquations(const std::vector<HeadSample>& S,
                                const HeadModel& head,
                                double t_mid,
                                const Noise& noise,
                                RateFit& fit) {
    constexpr double kH = 0.05;
    const Eigen::Vector4d& x = fit.x;
    fit.info.setZero();
    Eigen::Vector4d g = Eigen::Vector4d::Zero();
    fit.n_res = 0;
    for (std::size_t i = 0; i < S.size(); ++i) {
        if (!fit.valid[i]) continue;
        const double tau = x[0] + x[1] * 1e-6 * (S[i].t - t_mid);
        const auto plus = head.At(S[i].t + tau + kH), minus = head.At(S[i].t + tau - kH);
        if (!plus || !minus) continue;
        const Eigen::Vector2d rate = HeadModel::Diff(*plus, *minus) / (2 * kH);
        for (int a = 0; a < 2; ++a) {
            Eigen::Vector4d J(-rate[a], -rate[a] * 1e-6 * (S[i].t - t_mid), 0, 0);
            J[2 + a] = -1;
            const double r = fit.res[i][a];
            const double w = 1.0 / (1.0 + (r / noise.scale) * (r / noise.scale)) / noise.variance;
            fit.info += w * J * J.transpose();
            g += w * J * r;
            ++fit.n_res;
        }
    }
    return g;
}

// Gauss-Newton on the clock model from x0, with a prior on the rate (rate_prior_sigma_ppm).
// On return res, valid and ss are those at the last step's start; info is that step's.
RateFit FitClockRate(const std::vector<HeadSample>& S,
                     const HeadModel& head,
                     double t_mid,
                     const Eigen::Vector4d& x0,
                     const ClockRateConfig& cfg) {
    RateFit fit;
    fit.x = x0;
    fit.res.resize(S.size());
    fit.valid.resize(S.size());
    for (int it = 0; it < cfg.max_iterations; ++it) {
        const Noise noise = Residuals(S, head, t_mid, cfg, fit);
        if (noise.scale <= 0) break;
        Eigen::Vector4d g = NormalEquations(S, head, t_mid, noise, fit);
        if (fit.n_res < 8) break;
        const double prior = 1.0 / (cfg.rate_prior_sigma_ppm * cfg.rate_prior_sigma_ppm);
        fit.info(1, 1) += prior;
        g[1] += prior * fit.x[1];
        const Eigen::Vector4d step = fit.info.ldlt().solve(-g);
        if (!step.allFinite()) break;
        fit.x += step;
        if (std::abs(step[0]) < 1e-6 && std::abs(step[1]) < 1e-3) break;
    }
    return fit;
}

// The estimate's message: the rate, and why it is not used when it is not.
std::string RateMessage(const ClockRateEstimate& est, double span_s, bool certain, bool fits) {
    char buf[320];
    std::snprintf(buf,
                  sizeof(buf),
                  "clock rate %+.1f ppm +- %.1f ppm from the head's attitude (%lld pings over "
                  "%.0f s, residual %.3f deg; it matches the INS %+.4f s +- %.4f s from the "
                  "ping times)",
                  est.rate_ppm,
                  est.rate_sigma_ppm,
                  static_cast<long long>(est.samples),
                  span_s,
                  est.residual_rms_deg,
                  est.offset_s,
                  est.offset_sigma_s);
    std::string message = buf;
    if (!est.found) {
        message = "clock rate: not used: " + message.substr(std::strlen("clock rate ")) +
                  (!fits      ? ": the head's attitude does not follow the INS"
                   : !certain ? ": too uncertain"
                              : ": beyond any clock crystal");
    }
    return message;
}

}  // namespace

ClockRateEstimate EstimateSonarClockRate(const survey::PingSeries& pings,
                                         const survey::NavSeries& nav,
                                         const ClockRateConfig& cfg) {
    ClockRateEstimate est;
    if (nav.samples.size() < 2) {
        est.message = "clock rate: no navigation";
        return est;
    }
    const std::int64_t t_ref = nav.samples.front().utime_gps;
    std::vector<HeadSample> all = HeadSamples(pings, t_ref);
    const double span = all.size() > 1 ? all.back().t - all.front().t : 0.0;
    if (static_cast<std::int64_t>(all.size()) < cfg.min_samples || span < cfg.min_span_s) {
        char buf[320];
        std::snprintf(buf,
                      sizeof(buf),
                      "clock rate: not estimated: %lld pings over %.0f s carry the head's own "
                      "attitude (at least %lld over %.0f s needed)",
                      static_cast<long long>(all.size()),
                      span,
                      static_cast<long long>(cfg.min_samples),
                      cfg.min_span_s);
        est.message = buf;
        return est;
    }
    const std::vector<HeadSample> S = ThinHeadSamples(std::move(all), cfg.max_samples);
    const double t_mid = 0.5 * (S.front().t + S.back().t);
    est.reference_utime = t_ref + std::llround(t_mid * 1e6);
    est.samples = static_cast<std::int64_t>(S.size());
    const HeadModel head(nav, t_ref, cfg.R_vehicle_sonar);

    const auto [best_d, best] = ScanOffset(S, head, cfg);
    if (!std::isfinite(best)) {
        est.message = "clock rate: not estimated: the pings lie outside the navigation span";
        return est;
    }
    Eigen::Vector4d x0(best_d, 0, 0, 0);
    x0.tail<2>() = MeanDifference(S, head, best_d);
    RateFit fit = FitClockRate(S, head, t_mid, x0, cfg);
    if (fit.n_res < 8 || !fit.x.allFinite()) {
        est.message = "clock rate: not estimated: the head's attitude could not be fitted";
        return est;
    }
    Residuals(S, head, t_mid, cfg, fit);
    const Eigen::Matrix4d C = fit.info.ldlt().solve(Eigen::Matrix4d::Identity());
    const auto n_ok = static_cast<std::size_t>(std::count(fit.valid.begin(), fit.valid.end(), 1));
    est.offset_s = fit.x[0];
    est.rate_ppm = fit.x[1];
    est.offset_sigma_s = std::sqrt(std::max(0.0, C(0, 0)));
    est.rate_sigma_ppm = std::sqrt(std::max(0.0, C(1, 1)));
    est.residual_rms_deg = n_ok > 0 ? std::sqrt(fit.ss / static_cast<double>(2 * n_ok)) : 0.0;
    const bool certain = est.rate_sigma_ppm <= cfg.max_rate_sigma_ppm;
    const bool plausible = std::abs(est.rate_ppm) <= cfg.max_abs_rate_ppm;
    const bool fits = est.residual_rms_deg <= cfg.max_residual_rms_deg;
    est.found = certain && plausible && fits;
    est.message = RateMessage(est, S.back().t - S.front().t, certain, fits);
    return est;
}

namespace {

// The header aids of pings [begin, end) on GPS time (seconds since t_ref): the positions of
// the first ping carrying each new fix, and the head's roll and pitch.
struct SegmentAids {
    std::vector<AidSample> pos, att;
};

SegmentAids AidsOf(const std::vector<survey::PingHeader>& P,
                   std::size_t begin,
                   std::size_t end,
                   std::int64_t t_ref,
                   const NavTrack& track) {
    SegmentAids a;
    double last_lat = std::numeric_limits<double>::quiet_NaN(), last_lon = last_lat;
    for (std::size_t k = begin; k < end; ++k) {
        const auto& h = P[k];
        const double t = static_cast<double>(h.utime_gps - t_ref) * 1e-6;
        if (std::isfinite(h.aid_latitude_deg) && std::isfinite(h.aid_longitude_deg) &&
            (h.aid_latitude_deg != last_lat || h.aid_longitude_deg != last_lon)) {
            const Eigen::Vector3d e =
                track.world().ToEnu({h.aid_latitude_deg, h.aid_longitude_deg, 0.0});
            a.pos.push_back({t, e.x(), e.y(), 0, 0, 0});
        }
        last_lat = h.aid_latitude_deg;
        last_lon = h.aid_longitude_deg;
        if (std::isfinite(h.aid_roll_deg) && std::isfinite(h.aid_pitch_deg))
            a.att.push_back({t, 0, 0, h.aid_roll_deg, h.aid_pitch_deg, 0});
    }
    return a;
}

// The de-biased RMS (deg) of the head's roll/pitch against the INS composed with the mount,
// with c added to the ping times; +inf when too few fall in the navigation span.
double HeadAttitudeMisfit(const std::vector<AidSample>& s,
                          const NavTrack& nav,
                          double c,
                          const Eigen::Matrix3d& R_vs,
                          bool identity) {
    Eigen::Vector2d sum = Eigen::Vector2d::Zero(), sq = Eigen::Vector2d::Zero();
    std::size_t n = 0;
    for (const auto& x : s) {
        const auto p = HeadRollPitch(nav, x.t + c, R_vs, identity);
        if (!p) continue;
        const Eigen::Vector2d r(WrapDeg(x.roll - p->x()), WrapDeg(x.pitch - p->y()));
        sum += r;
        sq += r.cwiseProduct(r);
        ++n;
    }
    if (n < std::max<std::size_t>(5, s.size() / 2)) return std::numeric_limits<double>::infinity();
    const Eigen::Vector2d mean = sum / static_cast<double>(n);
    return std::sqrt(std::max(0.0, (sq / static_cast<double>(n) - mean.cwiseProduct(mean)).sum()));
}

double MedianInterval(const std::vector<survey::PingHeader>& P) {
    std::vector<double> per, all;
    for (std::size_t k = 1; k < P.size(); ++k) {
        const double dt = static_cast<double>(P[k].utime_gps - P[k - 1].utime_gps) * 1e-6;
        const std::int64_t dn = P[k].ping_number - P[k - 1].ping_number;
        all.push_back(dt);
        if (dn >= 1 && dn <= 10) per.push_back(dt / static_cast<double>(dn));
    }
    return Median(per.size() >= all.size() / 2 ? per : all);
}

// Pings that come before pings of lower number. A clock set back interleaves the pings of both
// sides in time order: the ping numbers drop and climb back above where they were within a few
// pings, dropping again on the way. A reset of the numbers (a restarted sonar) drops once and
// climbs from zero. Returns the count; `first` the first such ping.
std::int64_t InterleavedPings(const std::vector<survey::PingHeader>& P, std::size_t* first) {
    constexpr std::size_t kInterleaveWindow = 50;
    std::int64_t backward = 0;
    for (std::size_t k = 1; k < P.size(); ++k) {
        if (P[k].ping_number >= P[k - 1].ping_number) continue;
        std::int64_t drops = 0;
        bool back_above = false;
        for (std::size_t j = k; j < P.size() && j < k + kInterleaveWindow; ++j) {
            drops += P[j].ping_number < P[j - 1].ping_number ? 1 : 0;
            back_above |= P[j].ping_number > P[k - 1].ping_number;
        }
        if (drops >= 2 && back_above) {
            if (backward == 0) *first = k;
            ++backward;
        }
    }
    return backward;
}

// A jump of the header times beyond what the ping numbers say: before ping k, jump_s more than
// dn ping intervals.
struct TimeJump {
    std::size_t k;
    double jump_s;
};

// The jumps over max(min_jump_s, 2 T) (T the ping interval), at most max_candidates of them
// (the largest), in ping order.
std::vector<TimeJump> TimeJumps(const std::vector<survey::PingHeader>& P,
                                double T,
                                const ClockStepConfig& cfg) {
    std::vector<TimeJump> jumps;
    for (std::size_t k = 1; k < P.size(); ++k) {
        const std::int64_t dn = P[k].ping_number - P[k - 1].ping_number;
        if (dn < 1 || dn > 50) continue;  // a reset or a long dropout: nothing to compare
        const double dt = static_cast<double>(P[k].utime_gps - P[k - 1].utime_gps) * 1e-6;
        const double jump = dt - static_cast<double>(dn) * T;
        if (jump > std::max(cfg.min_jump_s, 2 * T)) jumps.push_back({k, jump});
    }
    if (static_cast<int>(jumps.size()) > cfg.max_candidates) {
        std::partial_sort(jumps.begin(),
                          jumps.begin() + cfg.max_candidates,
                          jumps.end(),
                          [](const TimeJump& a, const TimeJump& b) { return a.jump_s > b.jump_s; });
        jumps.resize(static_cast<std::size_t>(cfg.max_candidates));
    }
    std::sort(
        jumps.begin(), jumps.end(), [](const TimeJump& a, const TimeJump& b) { return a.k < b.k; });
    return jumps;
}

// A segment's clock offset against the INS, s.
struct SegmentOffset {
    bool ok = false;
    double d = 0, sigma = 0;
};

// Each segment [bounds[i], bounds[i + 1]) of pings matched against the INS on its own: by the
// head's attitude where the segments carry enough of it, else by the header fixes (`method`
// says which). The scan spans +- scan_s.
std::vector<SegmentOffset> SegmentOffsets(const std::vector<survey::PingHeader>& P,
                                          const std::vector<std::size_t>& bounds,
                                          const NavTrack& track,
                                          std::int64_t t_ref,
                                          double T,
                                          double scan_s,
                                          const ClockStepConfig& cfg,
                                          std::string* method) {
    const bool identity = cfg.R_vehicle_sonar.isIdentity(1e-12);
    const std::size_t num_seg = bounds.size() - 1;
    std::vector<SegmentAids> aids(num_seg);
    std::int64_t att_total = 0;
    for (std::size_t i = 0; i < num_seg; ++i) {
        aids[i] = AidsOf(P, bounds[i], bounds[i + 1], t_ref, track);
        att_total += static_cast<std::int64_t>(aids[i].att.size());
    }
    const bool use_attitude = att_total >= cfg.min_aid_samples * static_cast<std::int64_t>(2);
    *method = use_attitude ? "header attitude" : "header position";
    std::vector<SegmentOffset> off(num_seg);
    for (std::size_t i = 0; i < num_seg; ++i) {
        std::vector<AidSample> a = Thin(use_attitude ? aids[i].att : aids[i].pos, 3000);
        if (static_cast<std::int64_t>(a.size()) <
            (use_attitude ? cfg.min_aid_samples : cfg.min_aid_samples / 3))
            continue;
        const auto score = [&](double c) {
            return use_attitude ? HeadAttitudeMisfit(a, track, c, cfg.R_vehicle_sonar, identity)
                                : PositionMisfit(a, track, c, 0.5);
        };
        const ScanResult sr = Scan(score, -scan_s, scan_s, cfg.scan_step_s, 1e9);
        if (!std::isfinite(sr.best)) continue;
        const double h = cfg.scan_step_s;
        off[i].ok = true;
        off[i].d =
            ParabolaVertex(sr.best_c, h, score(sr.best_c - h), sr.best, score(sr.best_c + h));
        // Waves resolve a segment's timing to about a scan step; a position fix to its age's
        // spread (a ping interval and the serial latency).
        off[i].sigma = use_attitude ? h
                                    : std::hypot(T / std::sqrt(12.0), 0.1) /
                                          std::sqrt(std::max(1.0, a.size() / 10.0));
    }
    return off;
}

// Each jump as a step (the offsets on its two sides differ beyond their sigma: r.steps,
// resolved), a pause (they agree: r.pauses) or unresolved (a side without an offset: r.steps).
// Consecutive segments on one clock form a group: returns each segment's group.
std::vector<int> ClassifyJumps(const std::vector<survey::PingHeader>& P,
                               const std::vector<std::size_t>& bounds,
                               const std::vector<TimeJump>& jumps,
                               const std::vector<SegmentOffset>& off,
                               const ClockStepConfig& cfg,
                               ClockStepResult& r) {
    std::vector<int> group(bounds.size() - 1, 0);
    for (std::size_t i = 1; i < group.size(); ++i) {
        ClockStep st;
        st.ping_index = bounds[i];
        st.ping_number = P[bounds[i]].ping_number;
        st.utime = P[bounds[i]].utime_gps;
        st.jump_s = jumps[i - 1].jump_s;
        group[i] = group[i - 1];
        if (!off[i - 1].ok || !off[i].ok) {
            r.steps.push_back(st);  // unresolved
            continue;
        }
        st.step_s = off[i - 1].d - off[i].d;
        st.sigma_s = std::hypot(off[i - 1].sigma, off[i].sigma);
        if (std::abs(st.step_s) > std::max(cfg.min_step_s, 4 * st.sigma_s)) {
            st.resolved = true;
            r.steps.push_back(st);
            group[i] = group[i - 1] + 1;
        } else {
            ++r.pauses;
        }
    }
    return group;
}

// The shift of each group's first ping against the reference group (the one with the most
// pings); each group's offset is its longest resolved segment's. Empty with one group.
std::vector<std::pair<std::size_t, double>> GroupShifts(const std::vector<std::size_t>& bounds,
                                                        const std::vector<int>& group,
                                                        const std::vector<SegmentOffset>& off) {
    const std::size_t num_seg = group.size();
    const int num_groups = group.back() + 1;
    std::vector<double> gd(static_cast<std::size_t>(num_groups), 0.0);
    std::vector<std::size_t> glen(static_cast<std::size_t>(num_groups), 0);
    std::vector<std::size_t> gsize(static_cast<std::size_t>(num_groups), 0);
    for (std::size_t i = 0; i < num_seg; ++i) {
        const auto g = static_cast<std::size_t>(group[i]);
        const std::size_t len = bounds[i + 1] - bounds[i];
        gsize[g] += len;
        if (off[i].ok && len > glen[g]) {
            glen[g] = len;
            gd[g] = off[i].d;
        }
    }
    const auto ref =
        static_cast<std::size_t>(std::max_element(gsize.begin(), gsize.end()) - gsize.begin());
    std::vector<std::pair<std::size_t, double>> shifts;
    if (num_groups <= 1) return shifts;
    for (std::size_t i = 0; i < num_seg; ++i) {
        if (i > 0 && group[i] == group[i - 1]) continue;
        const auto g = static_cast<std::size_t>(group[i]);
        shifts.push_back({bounds[i], g == ref ? 0.0 : gd[g] - gd[ref]});
    }
    return shifts;
}

std::string StepsMessage(const ClockStepResult& r, std::size_t num_jumps, double T) {
    char buf[400];
    std::int64_t resolved = 0, unresolved = 0;
    std::string first;
    for (const auto& st : r.steps) {
        (st.resolved ? resolved : unresolved) += 1;
        if (st.resolved && first.empty()) {
            std::snprintf(buf,
                          sizeof(buf),
                          "%+.3f s +- %.3f s at ping number %lld (ping %zu, %.3f GPS s)",
                          st.step_s,
                          st.sigma_s,
                          static_cast<long long>(st.ping_number),
                          st.ping_index,
                          static_cast<double>(st.utime) * 1e-6);
            first = buf;
        }
    }
    std::snprintf(buf,
                  sizeof(buf),
                  "clock steps (%s): %zu jumps of the header times beyond the %.3f s ping "
                  "interval: %lld steps of the topside clock, %lld pauses, %lld unresolved",
                  r.method.c_str(),
                  num_jumps,
                  T,
                  static_cast<long long>(resolved),
                  static_cast<long long>(r.pauses),
                  static_cast<long long>(unresolved));
    std::string message = buf;
    if (!first.empty()) message += "; first: " + first;
    return message;
}

}  // namespace

ClockStepResult FindSonarClockSteps(const survey::PingSeries& pings,
                                    const survey::NavSeries& nav,
                                    const ClockStepConfig& cfg) {
    ClockStepResult r;
    const auto& P = pings.pings;
    if (P.size() < 20 || nav.samples.size() < 2) {
        r.message = "clock steps: not checked (too few pings or navigation samples)";
        return r;
    }
    std::size_t first_back = 0;
    r.backward = InterleavedPings(P, &first_back);
    if (r.backward > 0) {
        char buf[400];
        std::snprintf(buf,
                      sizeof(buf),
                      "clock steps: the header times run backwards: %lld pings come before "
                      "pings of lower number (first near ping number %lld, %s): the topside "
                      "clock was set back and the pings on both sides interleave",
                      static_cast<long long>(r.backward),
                      static_cast<long long>(P[first_back].ping_number),
                      SpanText(P[first_back].utime_gps, P[first_back].utime_gps).c_str());
        r.message = buf;
        return r;
    }
    const double T = MedianInterval(P);
    const std::vector<TimeJump> jumps = TimeJumps(P, T, cfg);
    if (jumps.empty()) {
        r.message = "clock steps: none (the header times follow the ping numbers)";
        return r;
    }

    // Each segment's offset against the INS; the jumps between them classified.
    const std::int64_t t_ref = nav.samples.front().utime_gps;
    const NavTrack track(nav, t_ref, cfg.antenna_lever_arm_m);
    std::vector<std::size_t> bounds = {0};
    for (const auto& j : jumps) bounds.push_back(j.k);
    bounds.push_back(P.size());
    const double scan_s = std::max(cfg.scan_s, 1.5 * jumps.back().jump_s);
    const std::vector<SegmentOffset> off =
        SegmentOffsets(P, bounds, track, t_ref, T, scan_s, cfg, &r.method);
    const std::vector<int> group = ClassifyJumps(P, bounds, jumps, off, cfg, r);
    r.segment_shift_s = GroupShifts(bounds, group, off);
    r.message = StepsMessage(r, jumps.size(), T);
    return r;
}

void ApplyClockSteps(survey::PingSeries& pings, const ClockStepResult& steps) {
    auto& P = pings.pings;
    for (std::size_t i = 0; i < steps.segment_shift_s.size(); ++i) {
        const std::size_t b = steps.segment_shift_s[i].first;
        const std::size_t e =
            i + 1 < steps.segment_shift_s.size() ? steps.segment_shift_s[i + 1].first : P.size();
        const auto d =
            static_cast<std::int64_t>(std::llround(steps.segment_shift_s[i].second * 1e6));
        for (std::size_t k = b; k < e && k < P.size(); ++k) P[k].utime_gps += d;
    }
    // A shift may move a segment's pings past its neighbour's: keep the series sorted.
    std::stable_sort(
        P.begin(), P.end(), [](const auto& a, const auto& b) { return a.utime_gps < b.utime_gps; });
}

double HeaderPositionMisfit(const survey::PingSeries& pings,
                            const survey::NavSeries& nav,
                            double correction_s,
                            const ClockSearchConfig& cfg) {
    const auto& P = pings.pings;
    if (P.size() < 2 || nav.samples.size() < 2) return std::numeric_limits<double>::infinity();
    const std::int64_t t_ref = nav.samples.front().utime_gps;
    const NavTrack track(nav, t_ref, cfg.antenna_lever_arm_m);
    const SegmentAids a = AidsOf(P, 0, P.size(), t_ref, track);
    if (a.pos.size() < 10) return std::numeric_limits<double>::infinity();
    const double p0 = static_cast<double>(P.front().utime_gps - t_ref) * 1e-6;
    const double p1 = static_cast<double>(P.back().utime_gps - t_ref) * 1e-6;
    const double age =
        cfg.assumed_fix_latency_s + 0.5 * (p1 - p0) / static_cast<double>(P.size() - 1);
    return PositionMisfit(
        Thin(a.pos, cfg.max_samples), track, correction_s - age, cfg.min_overlap_fraction);
}

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

namespace {

// The header aids of all pings on the sonar's clock (seconds since t_ref): the positions of the
// first ping carrying each new fix, and the attitudes (roll and pitch, heading, either).
struct HeaderAids {
    std::vector<AidSample> pos, att;
    bool have_heading = false, have_roll_pitch = false;
};

HeaderAids HeaderAidsOf(const survey::PingSeries& pings,
                        std::int64_t t_ref,
                        const NavTrack& track) {
    HeaderAids a;
    double last_lat = std::numeric_limits<double>::quiet_NaN(), last_lon = last_lat;
    for (const auto& h : pings.pings) {
        const double t = static_cast<double>(h.utime_gps - t_ref) * 1e-6;
        if (std::isfinite(h.aid_latitude_deg) && std::isfinite(h.aid_longitude_deg) &&
            (h.aid_latitude_deg != last_lat || h.aid_longitude_deg != last_lon)) {
            // First ping that carries this fix: the fix is at most a ping interval old.
            const Eigen::Vector3d e =
                track.world().ToEnu({h.aid_latitude_deg, h.aid_longitude_deg, 0.0});
            a.pos.push_back({t, e.x(), e.y(), 0, 0, 0});
        }
        last_lat = h.aid_latitude_deg;
        last_lon = h.aid_longitude_deg;
        const bool rp = std::isfinite(h.aid_roll_deg) && std::isfinite(h.aid_pitch_deg);
        const bool hd = std::isfinite(h.aid_heading_deg);
        if (rp || hd) {
            a.att.push_back({t,
                             0,
                             0,
                             rp ? h.aid_roll_deg : 0.0,
                             rp ? h.aid_pitch_deg : 0.0,
                             hd ? h.aid_heading_deg : 0.0});
            a.have_roll_pitch |= rp;
            a.have_heading |= hd;
        }
    }
    return a;
}

// The span of clock corrections c to scan: every c that overlaps the pings' and the
// navigation's spans at all, on the coarse step.
struct ClockScan {
    double lo = 0, hi = 0, step = 0;
    double p0 = 0, p1 = 0;     // first and last ping, seconds since t_ref
    double ping_interval = 0;  // mean, s
};

ClockScan ScanRange(const survey::PingSeries& pings,
                    std::int64_t t_ref,
                    const NavTrack& track,
                    const ClockSearchConfig& cfg) {
    ClockScan r;
    r.p0 = static_cast<double>(pings.pings.front().utime_gps - t_ref) * 1e-6;
    r.p1 = static_cast<double>(pings.pings.back().utime_gps - t_ref) * 1e-6;
    r.lo = track.first() - r.p1;
    r.hi = track.last() - r.p0;
    r.ping_interval = (r.p1 - r.p0) / static_cast<double>(pings.pings.size() - 1);
    r.step = std::max(cfg.scan_step_s, (r.hi - r.lo) / 200000.0);
    return r;
}

// The estimate from a coarse scan: a fine scan of `score` around the coarse minimum, then a
// parabola through the best three; found unless the fit is poor (misfit over `limit`) or
// ambiguous (an alias almost as good). stale_s is the aids' own age (the systematic part of the
// sigma); `unit` the misfit's, for the message.
template <class Score>
void Refine(const ScanResult& coarse,
            const Score& score,
            double limit,
            const char* unit,
            double stale_s,
            const ClockSearchConfig& cfg,
            ClockEstimate& est) {
    const ScanResult fine = Scan(score,
                                 coarse.best_c - cfg.fine_window_s,
                                 coarse.best_c + cfg.fine_window_s,
                                 cfg.fine_step_s,
                                 1e9);
    const double h = cfg.fine_step_s;
    est.correction_s =
        ParabolaVertex(fine.best_c, h, score(fine.best_c - h), fine.best, score(fine.best_c + h));
    est.misfit = score(est.correction_s);
    if (!std::isfinite(est.misfit)) est.misfit = fine.best;
    est.alias_misfit = coarse.alias;
    est.alias_correction_s = coarse.alias_c;
    // The statistical part is small beside the aids' age.
    est.sigma_s = std::hypot(stale_s, cfg.fine_step_s);
    // Both on the coarse grid: a refined best against an unrefined alias would hide it.
    const bool ambiguous = coarse.alias > 0 && coarse.alias < cfg.alias_ratio * coarse.best;
    const bool poor = !(est.misfit <= limit);
    est.found = !ambiguous && !poor;
    char buf[320];
    // No offset fitting at all says more than two that fit equally badly: the aids of another
    // survey (or a broken feed) fit nowhere, whatever the clock.
    if (poor) {
        std::snprintf(buf,
                      sizeof(buf),
                      "%s: no offset fits: the best, %+.3f s, still leaves a misfit of %.3g "
                      "%s (limit %.3g): the 83P headers match this navigation nowhere (a "
                      "file of another survey, or another vehicle's aids?)",
                      est.method.c_str(),
                      est.correction_s,
                      est.misfit,
                      unit,
                      limit);
    } else if (ambiguous) {
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
}

// The correction that puts the headers' fixes on the navigation's track.
ClockEstimate FromHeaderPositions(std::vector<AidSample> pos,
                                  const NavTrack& track,
                                  const ClockScan& range,
                                  const ClockSearchConfig& cfg) {
    ClockEstimate est;
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
             range.lo,
             range.hi,
             range.step,
             cfg.min_alias_separation_s);
    // A fix reaches the topside a serial latency (~0.1-0.2 s) after its epoch and shows in the
    // next ping: up to a ping interval later.
    Refine(coarse,
           score,
           cfg.max_position_misfit_m,
           "m",
           std::hypot(range.ping_interval / std::sqrt(12.0), cfg.fix_latency_sigma_s),
           cfg,
           est);
    // The fix a ping carries is older than the ping: the match found the fix's epoch, which is
    // `age` before the ping.
    const double age = cfg.assumed_fix_latency_s + 0.5 * range.ping_interval;
    est.correction_s += age;
    if (est.found) {
        char buf[320];
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

// The correction that matches the headers' attitudes to the INS's: heading places it (turns
// are unique), roll and pitch refine it where both are there.
ClockEstimate FromHeaderAttitudes(HeaderAids aids,
                                  const NavTrack& track,
                                  const ClockScan& range,
                                  const ClockSearchConfig& cfg) {
    ClockEstimate est;
    est.method = "header attitude";
    const std::vector<AidSample> att = Thin(std::move(aids.att), cfg.max_samples);
    est.samples = static_cast<std::int64_t>(att.size());
    const AttitudeUse coarse_use =
        aids.have_heading ? AttitudeUse::kHeading : AttitudeUse::kRollPitch;
    const std::vector<AidSample> few = Thin(att, cfg.max_coarse_samples);
    const ScanResult coarse = Scan(
        [&](double c) {
            return AttitudeMisfit(few, track, c, cfg.min_overlap_fraction, coarse_use);
        },
        range.lo,
        range.hi,
        range.step,
        cfg.min_alias_separation_s);
    // The roll and pitch of the waves are sharper locally than heading: the fine scan uses
    // them when the headers have both.
    const AttitudeUse fine_use =
        aids.have_heading && aids.have_roll_pitch ? AttitudeUse::kRollPitch : coarse_use;
    const auto score = [&](double c) {
        return AttitudeMisfit(att, track, c, cfg.min_overlap_fraction, fine_use);
    };
    Refine(coarse, score, cfg.max_attitude_misfit_deg, "deg", 0.5 * range.ping_interval, cfg, est);
    return est;
}

// Nothing but the clock: assume the two recordings ran at the same time.
ClockEstimate FromSpans(const NavTrack& track, const ClockScan& range) {
    ClockEstimate est;
    est.method = "span";
    const double nav_len = track.last() - track.first();
    const double ping_len = range.p1 - range.p0;
    est.correction_s = 0.5 * (track.first() + track.last()) - 0.5 * (range.p0 + range.p1);
    est.sigma_s = std::abs(nav_len - ping_len) / (2.0 * std::sqrt(3.0));
    est.found = true;
    char buf[320];
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

}  // namespace

ClockEstimate EstimateSonarClock(const survey::PingSeries& pings,
                                 const survey::NavSeries& nav,
                                 const ClockSearchConfig& cfg) {
    if (pings.pings.size() < 2 || nav.samples.size() < 2) {
        ClockEstimate est;
        est.method = "none";
        est.message = "too few pings or navigation samples to find the sonar clock";
        return est;
    }
    const std::int64_t t_ref = nav.samples.front().utime_gps;
    const NavTrack track(nav, t_ref, cfg.antenna_lever_arm_m);
    const ClockScan range = ScanRange(pings, t_ref, track, cfg);
    HeaderAids aids = HeaderAidsOf(pings, t_ref, track);
    if (aids.pos.size() >= 10) return FromHeaderPositions(std::move(aids.pos), track, range, cfg);
    if (aids.att.size() >= 10) return FromHeaderAttitudes(std::move(aids), track, range, cfg);
    return FromSpans(track, range);
}

}  // namespace pitmap::proc::calib
