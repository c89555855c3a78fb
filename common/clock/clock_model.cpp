// SPDX-License-Identifier: MIT
#include "common/clock/clock_model.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace pitmap::clock {
namespace {

constexpr double kMicrosPerSecondD = 1e6;

std::int64_t RoundToInt64(double v) {
    return static_cast<std::int64_t>(std::llround(v));
}

// Cross product of (a - o) x (b - o); > 0 for a counter-clockwise turn o -> a -> b.
double Cross(double ox, double oy, double ax, double ay, double bx, double by) {
    return (ax - ox) * (by - oy) - (ay - oy) * (bx - ox);
}

}  // namespace

const char* ToString(ClockState state) {
    switch (state) {
        case ClockState::kNoTime:
            return "no_time";
        case ClockState::kConverging:
            return "converging";
        case ClockState::kLocked:
            return "locked";
        case ClockState::kHoldover:
            return "holdover";
    }
    return "unknown";
}

// ---------------------------------------------------------------------------------------------
LowerEnvelope::LowerEnvelope(const LowerEnvelopeConfig& config) : config_(config) {}

void LowerEnvelope::Clear() {
    points_.clear();
    last_x_ = 0;
    num_samples_ = 0;
    residual_ms2_ = 0.0;
    have_residual_ = false;
    slope_fitted_ = false;
    line_ = {};
}

double LowerEnvelope::residual_rms() const {
    return std::sqrt(residual_ms2_);
}

void LowerEnvelope::Add(std::int64_t x, std::int64_t y) {
    if (num_samples_ > 0) {
        const double r = static_cast<double>(y) - line_.At(x);
        if (!have_residual_) {
            residual_ms2_ = r * r;
            have_residual_ = true;
        } else {
            residual_ms2_ += config_.residual_ema_alpha * (r * r - residual_ms2_);
        }
    }
    const bool same_bucket = config_.bucket_us > 0 && !points_.empty() &&
                             x / config_.bucket_us == points_.back().x / config_.bucket_us;
    if (same_bucket) {
        Point& b = points_.back();
        if (y < b.y) {
            b.x = x;
            b.y = y;
        }
        ++b.count;
    } else {
        points_.push_back({x, y, 1});
    }
    ++num_samples_;
    last_x_ = x;
    while (!points_.empty() &&
           (points_.front().x < x - config_.window_us || points_.size() > config_.max_buckets)) {
        num_samples_ -= points_.front().count;
        points_.pop_front();
    }
    Refit();
}

void LowerEnvelope::Refit() {
    // Coordinates relative to the oldest point keep the products well inside double precision.
    const std::int64_t x0 = points_.front().x;
    const std::int64_t y0 = points_.front().y;
    double sum_w = 0.0;
    double sum_wx = 0.0;
    for (const Point& p : points_) {
        sum_w += p.count;
        sum_wx += p.count * static_cast<double>(p.x - x0);
    }
    const double x_bar = sum_wx / sum_w;
    const double span = static_cast<double>(points_.back().x - x0);

    slope_fitted_ = false;
    double slope = config_.prior_slope;
    double y_at_bar = 0.0;
    if (points_.size() >= 2 && span >= static_cast<double>(config_.min_span_for_slope_us)) {
        // Lower hull, Andrew's monotone chain (x already increasing).
        std::vector<std::pair<double, double>> hull;
        hull.reserve(points_.size());
        for (const Point& p : points_) {
            const double px = static_cast<double>(p.x - x0);
            const double py = static_cast<double>(p.y - y0);
            while (hull.size() >= 2 && Cross(hull[hull.size() - 2].first,
                                             hull[hull.size() - 2].second,
                                             hull.back().first,
                                             hull.back().second,
                                             px,
                                             py) <= 0.0) {
                hull.pop_back();
            }
            hull.emplace_back(px, py);
        }
        // The edge over the centroid minimises the summed vertical gap (see the header), but
        // two neighbouring vertices give a noisy slope. The chord between the hull vertices
        // nearest to x_bar -/+ span/4 has a baseline of about half the window, so its slope
        // error is (envelope noise) / (span / 2); the offset is then fitted below every point.
        const double lo_x = x_bar - span / 4.0;
        const double hi_x = x_bar + span / 4.0;
        std::size_t ia = 0;
        while (ia + 1 < hull.size() && hull[ia + 1].first <= lo_x) ++ia;
        std::size_t ib = hull.size() - 1;
        while (ib > 0 && hull[ib - 1].first >= hi_x) --ib;
        if (ib <= ia) {
            // Too few vertices for the chord: the edge over the centroid.
            ia = 0;
            while (ia + 2 < hull.size() && hull[ia + 1].first < x_bar) ++ia;
            ib = std::min(ia + 1, hull.size() - 1);
        }
        const auto& a = hull[ia];
        const auto& b = hull[ib];
        if (b.first > a.first) {
            const double s = (b.second - a.second) / (b.first - a.first);
            if (std::abs(s) <= config_.max_abs_slope) {
                slope = s;
                slope_fitted_ = true;
            }
        }
    }
    {
        // The highest line of this slope that stays under every point (touches the hull).
        double best = std::numeric_limits<double>::infinity();
        for (const Point& p : points_) {
            const double px = static_cast<double>(p.x - x0);
            best = std::min(best, static_cast<double>(p.y - y0) - slope * (px - x_bar));
        }
        y_at_bar = best;
    }
    const std::int64_t x_ref_rel = RoundToInt64(x_bar);
    line_.x_ref = x0 + x_ref_rel;
    line_.slope = slope;
    line_.y_ref =
        static_cast<double>(y0) + y_at_bar + slope * (static_cast<double>(x_ref_rel) - x_bar);
}

// ---------------------------------------------------------------------------------------------
std::vector<std::string> ClockModelConfig::Validate() const {
    std::vector<std::string> p;
    if (envelope.window_us <= 0) p.push_back("clock: envelope.window_us must be > 0");
    if (envelope.bucket_us < 0) p.push_back("clock: envelope.bucket_us must be >= 0");
    if (envelope.max_buckets < 2) p.push_back("clock: envelope.max_buckets must be >= 2");
    if (envelope.min_span_for_slope_us <= 0) {
        p.push_back("clock: envelope.min_span_for_slope_us must be > 0");
    }
    if (!(envelope.max_abs_slope > 0.0)) p.push_back("clock: envelope.max_abs_slope must be > 0");
    if (!(envelope.residual_ema_alpha > 0.0 && envelope.residual_ema_alpha <= 1.0)) {
        p.push_back("clock: envelope.residual_ema_alpha must be in (0, 1]");
    }
    if (min_samples_for_lock < 2) p.push_back("clock: min_samples_for_lock must be >= 2");
    if (max_delay_us <= 0) p.push_back("clock: max_delay_us must be > 0");
    if (jump_confirm_samples < 1) p.push_back("clock: jump_confirm_samples must be >= 1");
    if (holdover_after_us <= 0 || max_holdover_us < holdover_after_us) {
        p.push_back("clock: need 0 < holdover_after_us <= max_holdover_us");
    }
    if (!(holdover_drift_ppm >= 0.0)) p.push_back("clock: holdover_drift_ppm must be >= 0");
    return p;
}

JumpGuardedEnvelope::JumpGuardedEnvelope(const ClockModelConfig& config)
    : config_(config), env_(config.envelope) {}

void JumpGuardedEnvelope::Clear() {
    env_.Clear();
    pending_.clear();
}

void JumpGuardedEnvelope::Reset() {
    if (!env_.empty() || !pending_.empty()) ++resets_;
    Clear();
}

ClockState JumpGuardedEnvelope::StateAt(std::int64_t x) const {
    if (env_.empty()) return ClockState::kNoTime;
    const std::int64_t age = x - env_.last_x();
    if (age > config_.max_holdover_us) return ClockState::kNoTime;
    if (age > config_.holdover_after_us) return ClockState::kHoldover;
    if (env_.num_samples() < config_.min_samples_for_lock || !env_.slope_fitted()) {
        return ClockState::kConverging;
    }
    return ClockState::kLocked;
}

double JumpGuardedEnvelope::StddevAt(std::int64_t x) const {
    if (env_.empty()) return 0.0;
    const double n = std::max(1, env_.num_samples());
    const double base = env_.residual_rms() / std::sqrt(n);
    const double span =
        std::max<double>(static_cast<double>(env_.last_x() - env_.first_x()), kMicrosPerSecondD);
    const double dist = std::abs(static_cast<double>(x - env_.line().x_ref));
    double s = base * (1.0 + 2.0 * dist / span);
    // Held slope: the drift is unknown up to the slope limit.
    if (!env_.slope_fitted()) s += dist * config_.envelope.max_abs_slope * 0.05;
    if (x > env_.last_x()) {
        s += config_.holdover_drift_ppm * 1e-6 * static_cast<double>(x - env_.last_x());
    }
    return s;
}

JumpGuardedEnvelope::AddResult JumpGuardedEnvelope::Add(std::int64_t x, std::int64_t y) {
    if (env_.empty() && pending_.empty()) {
        env_.Add(x, y);
        return AddResult::kAccepted;
    }
    bool consistent = false;
    if (!env_.empty() && x > env_.last_x()) {
        const double r = static_cast<double>(y) - env_.line().At(x);
        const double max_delay = static_cast<double>(config_.max_delay_us);
        // Once locked, a sample far below the envelope would need a negative delay.
        const double below = StateAt(x) == ClockState::kLocked
                                 ? std::clamp(4.0 * env_.residual_rms() + 1000.0, 1000.0, max_delay)
                                 : max_delay;
        consistent = r >= -below && r <= max_delay;
    }
    if (consistent) {
        outliers_ += static_cast<std::int64_t>(pending_.size());
        pending_.clear();
        env_.Add(x, y);
        return AddResult::kAccepted;
    }
    const bool agrees =
        !pending_.empty() && x > pending_.back().x &&
        std::abs(static_cast<double>(y - pending_.front().y)) <=
            static_cast<double>(config_.max_delay_us) +
                config_.envelope.max_abs_slope * static_cast<double>(x - pending_.front().x);
    if (!agrees) {
        outliers_ += static_cast<std::int64_t>(pending_.size());
        pending_.clear();
    }
    pending_.push_back({x, y});
    if (static_cast<std::int32_t>(pending_.size()) < config_.jump_confirm_samples) {
        return AddResult::kPending;
    }
    ++resets_;
    env_.Clear();
    for (const Sample& s : pending_) env_.Add(s.x, s.y);
    pending_.clear();
    return AddResult::kReset;
}

// ---------------------------------------------------------------------------------------------
std::vector<std::string> HostClockConfig::Validate() const {
    std::vector<std::string> p = model.Validate();
    if (fixed_latency_us < 0) p.push_back("host clock: fixed_latency_us must be >= 0");
    if (pps_window_us <= 0) p.push_back("host clock: pps_window_us must be > 0");
    if (pps_timeout_us <= 0) p.push_back("host clock: pps_timeout_us must be > 0");
    if (pps_max_label_error_us <= 0 || pps_max_label_error_us >= 500'000) {
        p.push_back("host clock: pps_max_label_error_us must be in (0, 500000)");
    }
    if (pps_min_samples < 2) p.push_back("host clock: pps_min_samples must be >= 2");
    return p;
}

HostClockModel::HostClockModel(const HostClockConfig& config)
    : config_(config), msg_(config.model) {}

void HostClockModel::AddMessage(std::int64_t utime_host, std::int64_t utime_gps, bool time_valid) {
    if (!time_valid || utime_gps < config_.min_plausible_gps_us) {
        // The receiver lost its time (reset, or not yet fixed): say so, invent nothing.
        if (!msg_.envelope().empty() || msg_.has_pending()) {
            ++receiver_resets_;
            msg_.Reset();
            pps_.clear();
        }
        return;
    }
    // y = host - GPS = (host - GPS at the epoch) + delay; the envelope removes the delay.
    const std::int64_t y = utime_host - config_.fixed_latency_us - utime_gps;
    if (msg_.Add(utime_host, y) == JumpGuardedEnvelope::AddResult::kReset) pps_.clear();
}

double HostClockModel::EnvelopeOffset(std::int64_t x) const {
    return -msg_.envelope().line().At(x);
}

bool HostClockModel::PpsActive(std::int64_t utime_host) const {
    return static_cast<std::int32_t>(pps_.size()) >= config_.pps_min_samples &&
           utime_host - pps_.back().first <= config_.pps_timeout_us &&
           msg_.StateAt(utime_host) != ClockState::kNoTime;
}

namespace {
// Least squares of (gps - host) against host over the PPS samples: returns offset at x_ref
// (the mean host time), slope and the RMS residual.
struct PpsFit {
    std::int64_t x_ref = 0;
    double offset = 0.0;
    double slope = 0.0;
    double rms = 0.0;
};
PpsFit FitPps(const std::deque<std::pair<std::int64_t, std::int64_t>>& pps) {
    const std::int64_t x0 = pps.front().first;
    const std::int64_t o0 = pps.front().second - pps.front().first;
    double sx = 0, so = 0;
    for (const auto& [h, g] : pps) {
        sx += static_cast<double>(h - x0);
        so += static_cast<double>((g - h) - o0);
    }
    const double n = static_cast<double>(pps.size());
    const double mx = sx / n, mo = so / n;
    double sxx = 0, sxo = 0;
    for (const auto& [h, g] : pps) {
        const double dx = static_cast<double>(h - x0) - mx;
        sxx += dx * dx;
        sxo += dx * (static_cast<double>((g - h) - o0) - mo);
    }
    PpsFit f;
    f.slope = sxx > 0 ? sxo / sxx : 0.0;
    f.x_ref = x0 + RoundToInt64(mx);
    f.offset = static_cast<double>(o0) + mo + f.slope * (static_cast<double>(f.x_ref - x0) - mx);
    double ss = 0;
    for (const auto& [h, g] : pps) {
        const double pred = f.offset + f.slope * static_cast<double>(h - f.x_ref);
        const double r = static_cast<double>(g - h) - pred;
        ss += r * r;
    }
    f.rms = std::sqrt(ss / n);
    return f;
}
}  // namespace

bool HostClockModel::AddPps(std::int64_t utime_host) {
    const GpsEstimate est = ToGps(utime_host);
    if (est.state == ClockState::kNoTime || (!pps_.empty() && utime_host <= pps_.back().first)) {
        ++pps_rejected_;
        return false;
    }
    const std::int64_t second = RoundToInt64(static_cast<double>(est.utime_gps) / 1e6);
    const std::int64_t label_us = second * 1'000'000;
    if (std::abs(est.utime_gps - label_us) > config_.pps_max_label_error_us) {
        ++pps_rejected_;
        return false;
    }
    pps_.emplace_back(utime_host, label_us);
    while (pps_.front().first < utime_host - config_.pps_window_us) pps_.pop_front();
    return true;
}

GpsEstimate HostClockModel::ToGps(std::int64_t utime_host) const {
    GpsEstimate e;
    e.state = msg_.StateAt(utime_host);
    if (e.state == ClockState::kNoTime) return e;
    if (PpsActive(utime_host)) {
        const PpsFit f = FitPps(pps_);
        e.utime_gps = utime_host +
                      RoundToInt64(f.offset + f.slope * static_cast<double>(utime_host - f.x_ref));
        e.state = ClockState::kLocked;
        e.stddev_us = f.rms / std::sqrt(static_cast<double>(pps_.size())) + 1.0;
        return e;
    }
    e.utime_gps = utime_host + RoundToInt64(EnvelopeOffset(utime_host));
    e.stddev_us = msg_.StddevAt(utime_host);
    return e;
}

ClockQuality HostClockModel::Quality(std::int64_t now) const {
    ClockQuality q;
    q.state = msg_.StateAt(now);
    q.resets = msg_.resets();
    q.outliers = msg_.outliers();
    if (msg_.envelope().empty()) return q;
    const LowerEnvelope& env = msg_.envelope();
    q.num_samples = env.num_samples();
    q.last_sample_utime = env.last_x();
    q.residual_rms_us = env.residual_rms();
    if (q.state != ClockState::kNoTime && PpsActive(now)) {
        const PpsFit f = FitPps(pps_);
        q.state = ClockState::kLocked;
        q.from_pps = true;
        q.ref_utime_in = f.x_ref;
        q.offset_us = RoundToInt64(f.offset);
        q.drift_ppm = f.slope * 1e6;
        q.residual_rms_us = f.rms;
        q.num_samples = static_cast<std::int32_t>(pps_.size());
        q.last_sample_utime = pps_.back().first;
        q.offset_stddev_us = ToGps(now).stddev_us;
        return q;
    }
    q.ref_utime_in = env.line().x_ref;
    q.offset_us = RoundToInt64(-env.line().y_ref);
    // GPS = host - line(host)  =>  d(GPS - host)/d(host) = -slope.
    q.drift_ppm = -env.line().slope * 1e6;
    q.offset_stddev_us = msg_.StddevAt(now);
    return q;
}

// ---------------------------------------------------------------------------------------------
std::vector<std::string> SonarClockConfig::Validate() const {
    std::vector<std::string> p = model.Validate();
    if (header_resolution_us < 0) p.push_back("sonar clock: header_resolution_us must be >= 0");
    return p;
}

SonarClockModel::SonarClockModel(const SonarClockConfig& config)
    : config_(config), env_(config.model) {}

double SonarClockModel::Correction() const {
    return config_.header_truncates ? 0.5 * static_cast<double>(config_.header_resolution_us) : 0.0;
}

SonarStamp SonarClockModel::Fallback(const SonarPingTimes& t) {
    ++fallbacks_;
    SonarStamp s;
    if (t.utime_gps_receive == 0) return s;
    s.utime_gps = t.utime_gps_receive - t.age_at_send_us;
    s.method = SonarStampMethod::kReceiveTime;
    s.state = ClockState::kConverging;
    // The transport delay is unknown up to max_delay_us: 1-sigma of a uniform spread.
    s.stddev_us = static_cast<double>(config_.model.max_delay_us) / std::sqrt(12.0);
    return s;
}

GpsEstimate SonarClockModel::ToGps(std::int64_t utime_header) const {
    GpsEstimate e;
    e.state = env_.StateAt(utime_header);
    if (e.state == ClockState::kNoTime || utime_header == 0) {
        e.state = ClockState::kNoTime;
        return e;
    }
    // y = GPS_receive - age - header = (GPS - header at the instant) + delay.
    e.utime_gps =
        utime_header + RoundToInt64(env_.envelope().line().At(utime_header) + Correction());
    e.stddev_us = env_.StddevAt(utime_header);
    return e;
}

SonarStamp SonarClockModel::Update(const SonarPingTimes& t) {
    if (t.utime_header == 0) return Fallback(t);
    if (t.utime_gps_receive != 0) {
        const std::int64_t y = t.utime_gps_receive - t.age_at_send_us - t.utime_header;
        if (env_.Add(t.utime_header, y) == JumpGuardedEnvelope::AddResult::kPending) {
            return Fallback(t);
        }
    }
    const GpsEstimate e = ToGps(t.utime_header);
    if (e.state == ClockState::kNoTime) return Fallback(t);
    return SonarStamp{e.utime_gps, SonarStampMethod::kHeaderModel, e.state, e.stddev_us};
}

ClockQuality SonarClockModel::Quality(std::int64_t now) const {
    ClockQuality q;
    q.state = env_.StateAt(now);
    q.resets = env_.resets();
    q.outliers = env_.outliers();
    if (env_.envelope().empty()) return q;
    const LowerEnvelope& env = env_.envelope();
    q.num_samples = env.num_samples();
    q.last_sample_utime = env.last_x();
    q.residual_rms_us = env.residual_rms();
    q.ref_utime_in = env.line().x_ref;
    q.offset_us = RoundToInt64(env.line().y_ref + Correction());
    q.drift_ppm = env.line().slope * 1e6;
    q.offset_stddev_us = env_.StddevAt(now);
    return q;
}

}  // namespace pitmap::clock
