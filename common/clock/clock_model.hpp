// SPDX-License-Identifier: MIT
// Clock models: host clock -> GPS time (from NovAtel message arrivals, optionally PPS) and
// Delta T 83P header clock -> GPS time. Pure maths: every time is passed in, nothing reads a
// clock, so tests drive them with synthetic truth.
//
// Both rest on the same observation (Harrison & Newman, "TICSync: Knowing when things
// happened", ICRA 2011): a message stamped by clock A at a_i and received at b_i on clock B
// satisfies  b_i - a_i = offset(a_i) + d_i  with a transport delay d_i >= 0. Fitting the
// line  y = alpha + beta (x - x_ref)  from below (the lower envelope of the points
// (x_i, y_i = b_i - a_i)) removes the delays without knowing their distribution. The line
// minimising sum_i (y_i - line(x_i)) subject to line(x_i) <= y_i is the edge of the lower
// convex hull that spans the centroid x_bar of the window (the objective is
// N * line(x_bar) - sum y_i), so one hull pass per update gives the estimate exactly.
// What remains is the minimum delay (the "delay floor"), which no method can see: the host
// model reports GPS time as if messages arrived with zero delay unless a fixed latency is
// configured.
//
// States follow clock_sync_t: NO_TIME (nothing usable: the stamp is 0, never an invented
// time), CONVERGING, LOCKED, HOLDOVER (no recent sample; extrapolating, for a bounded time).
#pragma once

#include <cstdint>
#include <deque>
#include <optional>
#include <string>
#include <vector>

namespace pitmap::clock {

enum class ClockState : std::int8_t {  // values of clock_sync_t.STATE_*
    kNoTime = 0,
    kConverging = 1,
    kLocked = 2,
    kHoldover = 3,
};
const char* ToString(ClockState state);

// y = y_ref + slope * (x - x_ref), x and y in microseconds.
struct EnvelopeLine {
    std::int64_t x_ref = 0;
    double y_ref = 0.0;
    double slope = 0.0;
    double At(std::int64_t x) const { return y_ref + slope * static_cast<double>(x - x_ref); }
};

struct LowerEnvelopeConfig {
    std::int64_t window_us = 60'000'000;              // samples older than this are dropped, us
    std::int64_t bucket_us = 100'000;                 // only the lowest sample per bucket is kept
                                                      // for the hull (0 = keep all), us
    std::size_t max_buckets = 4096;                   // hard memory cap on kept points
    std::int64_t min_span_for_slope_us = 10'000'000;  // below this span the slope is held at
                                                      // prior_slope, us
    double prior_slope = 0.0;                         // slope used before the span allows a fit
    double max_abs_slope = 1e-3;                      // a fitted |slope| above this (1000 ppm) is
                                                      // rejected in favour of prior_slope
    double residual_ema_alpha = 0.02;                 // weight of a new residual in the RMS
};

// Lower-envelope line fit over a sliding window of (x, y) samples with y >= line(x).
// x must increase from sample to sample (the caller handles clock steps).
class LowerEnvelope {
public:
    explicit LowerEnvelope(const LowerEnvelopeConfig& config = {});

    // Adds a sample. Precondition: empty() or x > last_x().
    void Add(std::int64_t x, std::int64_t y);
    void Clear();

    bool empty() const { return num_samples_ == 0; }
    std::int64_t last_x() const { return last_x_; }
    std::int64_t first_x() const { return points_.empty() ? last_x_ : points_.front().x; }
    // Samples added since the last Clear() that are still inside the window.
    std::int32_t num_samples() const { return num_samples_; }
    // True when the slope comes from a fit, false while it is held at the prior.
    bool slope_fitted() const { return slope_fitted_; }
    // Precondition: !empty().
    const EnvelopeLine& line() const { return line_; }
    // RMS of (y - line(x)) of recent samples, taken before each sample was added, us.
    double residual_rms() const;

private:
    struct Point {
        std::int64_t x;
        std::int64_t y;
        std::int32_t count;  // samples merged into this bucket
    };
    void Refit();

    LowerEnvelopeConfig config_;
    std::deque<Point> points_;
    std::int64_t last_x_ = 0;
    std::int32_t num_samples_ = 0;
    double residual_ms2_ = 0.0;  // EMA of squared residuals, us^2
    bool have_residual_ = false;
    bool slope_fitted_ = false;
    EnvelopeLine line_;
};

// The model's quality, mapped one to one onto clock_sync_t by the daemon (time_keeper.hpp).
struct ClockQuality {
    ClockState state = ClockState::kNoTime;
    std::int64_t ref_utime_in = 0;       // reference point of the model, input clock us
    std::int64_t offset_us = 0;          // GPS minus input clock at ref_utime_in, us
    double drift_ppm = 0.0;              // rate of GPS against the input clock - 1, ppm
    double residual_rms_us = 0.0;        // RMS of recent samples above the envelope, us
    double offset_stddev_us = 0.0;       // 1-sigma of the model at the query time, us (heuristic)
    std::int32_t num_samples = 0;        // samples in the current window
    std::int64_t last_sample_utime = 0;  // input-clock time of the newest sample, us
    std::int32_t resets = 0;             // model resets (clock jumps, receiver resets)
    std::int64_t outliers = 0;           // samples rejected as inconsistent
    bool from_pps = false;               // host model: the PPS fit is in use
};

// A time estimate: utime_gps = 0 whenever state == kNoTime.
struct GpsEstimate {
    std::int64_t utime_gps = 0;  // GPS microseconds since 1980-01-06; 0 = unknown
    ClockState state = ClockState::kNoTime;
    double stddev_us = 0.0;
};

// Shared tuning of both models.
struct ClockModelConfig {
    LowerEnvelopeConfig envelope{};
    std::int32_t min_samples_for_lock = 20;      // fewer samples in the window: CONVERGING
    std::int64_t max_delay_us = 250'000;         // largest believable transport delay, us
    std::int32_t jump_confirm_samples = 5;       // consecutive inconsistent samples that make a
                                                 // clock jump (fewer are dropped as outliers)
    std::int64_t holdover_after_us = 3'000'000;  // no sample for this long: HOLDOVER, us
    std::int64_t max_holdover_us = 300'000'000;  // no sample for this long: NO_TIME, us
    double holdover_drift_ppm = 2.0;  // assumed drift wander, grows the stddev in holdover

    std::vector<std::string> Validate() const;
};

// Detects clock steps on top of a LowerEnvelope: a sample is inconsistent when it lies more
// than a tolerance below the envelope (a negative delay), more than max_delay_us above it, or
// when x went backwards; jump_confirm_samples consecutive inconsistent samples that agree
// with each other reset the envelope and seed it with them.
class JumpGuardedEnvelope {
public:
    enum class AddResult { kAccepted, kPending, kReset };
    explicit JumpGuardedEnvelope(const ClockModelConfig& config);

    AddResult Add(std::int64_t x, std::int64_t y);
    void Clear();  // forgets everything, counts nothing
    void Reset();  // forgets everything and counts a reset

    const LowerEnvelope& envelope() const { return env_; }
    bool has_pending() const { return !pending_.empty(); }
    std::int32_t resets() const { return resets_; }
    std::int64_t outliers() const { return outliers_; }
    // The state at input-clock time x (no sample: kNoTime).
    ClockState StateAt(std::int64_t x) const;
    // 1-sigma at x (heuristic): envelope noise / sqrt(n), grown by the extrapolation distance
    // and by holdover_drift_ppm beyond the last sample.
    double StddevAt(std::int64_t x) const;

private:
    struct Sample {
        std::int64_t x;
        std::int64_t y;
    };
    ClockModelConfig config_;
    LowerEnvelope env_;
    std::vector<Sample> pending_;
    std::int32_t resets_ = 0;
    std::int64_t outliers_ = 0;
};

// Host clock (CLOCK_REALTIME, Unix us) -> GPS time.
struct HostClockConfig {
    ClockModelConfig model{};
    std::int64_t fixed_latency_us = 0;  // known constant part of the message delay (serial
                                        // transmission, receiver output latency), us
    std::int64_t min_plausible_gps_us =
        2000LL * 604'800 * 1'000'000;         // GPS week 2000
                                              // (2018): earlier times mean a receiver without time
    std::int64_t pps_window_us = 30'000'000;  // PPS samples kept for the fit, us
    std::int64_t pps_timeout_us = 2'500'000;  // without a pulse for this long, back to the
                                              // message envelope, us
    std::int64_t pps_max_label_error_us = 200'000;  // a pulse further than this from a whole
                                                    // GPS second (by the model) is rejected, us
    std::int32_t pps_min_samples = 3;               // pulses needed before the PPS fit is used

    std::vector<std::string> Validate() const;
};

class HostClockModel {
public:
    explicit HostClockModel(const HostClockConfig& config = {});

    // A NovAtel message received at utime_host (Unix us) whose header says utime_gps. Pass
    // time_valid = false when the header's time status is below FINE / the week is unknown:
    // after a locked model that means the receiver reset, so the model is cleared (NO_TIME)
    // and a reset is counted. Times before min_plausible_gps_us count as invalid.
    void AddMessage(std::int64_t utime_host, std::int64_t utime_gps, bool time_valid);
    // An RFC 2783 assert timestamp (host Unix us) of a PPS pulse, which marks a whole GPS
    // second. The second is labelled by the current model; without a model it is ignored.
    // Returns whether the pulse was used.
    bool AddPps(std::int64_t utime_host);

    // GPS time of host instant utime_host; utime_gps = 0 when the state is kNoTime.
    GpsEstimate ToGps(std::int64_t utime_host) const;
    ClockQuality Quality(std::int64_t utime_host_now) const;
    std::int64_t receiver_resets() const { return receiver_resets_; }
    std::int64_t pps_rejected() const { return pps_rejected_; }

private:
    bool PpsActive(std::int64_t utime_host) const;
    // GPS - host at x from the message envelope.
    double EnvelopeOffset(std::int64_t x) const;

    HostClockConfig config_;
    JumpGuardedEnvelope msg_;
    // PPS: least squares of (host, gps - host) over the window; pulses carry no queueing delay.
    std::deque<std::pair<std::int64_t, std::int64_t>> pps_;  // (host us, GPS us)
    std::int64_t receiver_resets_ = 0;
    std::int64_t pps_rejected_ = 0;
};

// Topside (83P header) clock -> GPS time.
struct SonarClockConfig {
    ClockModelConfig model{.envelope = {.window_us = 120'000'000, .bucket_us = 0},
                           .max_delay_us = 200'000};
    std::int64_t header_resolution_us = 1000;  // tick of the header clock: 1000 for v1.10
                                               // milliseconds, 10000 for v1.00 hundredths
    bool header_truncates = true;  // the header drops the fraction below one tick, so the
                                   // instant lies on average half a tick after the stamp
    std::vector<std::string> Validate() const;
};

// Times of one 83P record, as the daemon knows them.
struct SonarPingTimes {
    std::int64_t utime_header = 0;       // header date/time on the topside clock, Unix us
                                         // (0 = missing)
    std::int64_t utime_gps_receive = 0;  // receive time in GPS (host model), us; 0 = unknown
    std::int64_t age_at_send_us = 0;     // header instant -> datagram sent, from the header
                                         // latencies (v1.10: data latency), us; 0 if unknown
};

enum class SonarStampMethod : std::int8_t {
    kNone = 0,         // no time at all: utime_gps = 0
    kHeaderModel = 1,  // header clock through the fitted model
    kReceiveTime = 2,  // fallback: receive time minus the header's latencies
};

struct SonarStamp {
    std::int64_t utime_gps = 0;  // GPS time of the header instant, us; 0 = unknown
    SonarStampMethod method = SonarStampMethod::kNone;
    ClockState state = ClockState::kNoTime;
    double stddev_us = 0.0;
};

class SonarClockModel {
public:
    explicit SonarClockModel(const SonarClockConfig& config = {});

    // Learns from one record and returns its stamp. Falls back to the receive time when the
    // header clock is missing, or while a header jump is being confirmed.
    SonarStamp Update(const SonarPingTimes& times);
    // Maps a header time without learning (kNoTime without a model).
    GpsEstimate ToGps(std::int64_t utime_header) const;
    ClockQuality Quality(std::int64_t utime_header_now) const;
    std::int64_t fallbacks() const { return fallbacks_; }

private:
    SonarStamp Fallback(const SonarPingTimes& times);
    double Correction() const;

    SonarClockConfig config_;
    JumpGuardedEnvelope env_;
    std::int64_t fallbacks_ = 0;
};

}  // namespace pitmap::clock
