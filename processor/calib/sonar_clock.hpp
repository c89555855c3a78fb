// SPDX-License-Identifier: MIT
// The sonar clock, coarsely: how far the pings' times are from GPS time when the pings come from
// .83P files written by the topside program, whose PC clock is off by an unknown amount
// (seconds to hours, either sign; shared/specs/imagenex_deltat.md §1.4). Found from what the
// files carry besides the clock, before any sounding is looked at:
//
//  1. "header position": the latitude/longitude the topside program got from its NMEA feed. A
//     fix is repeated in every ping until the next one arrives, so only the first ping that
//     carries a new fix is used (the fix is then at most one ping interval plus the serial
//     latency old). The correction c minimises the median horizontal distance between those
//     fixes and the INS antenna position at (ping time + c): a scan over every c that makes the
//     two time spans overlap (step scan_step_s), then a parabola through the best three steps
//     of a finer scan; the fixes' mean age (assumed_fix_latency_s + half a ping interval) is
//     taken off.
//  2. "header attitude": no position, but the head's roll/pitch (internal sensor or the external
//     fields) and/or heading: the correction minimises the RMS of the de-biased differences to
//     the INS attitude (a constant difference is the mount). Heading decides the coarse scan
//     when present (turns are unique; wave roll is periodic and gives aliases).
//  3. "span": nothing but the clock. The two recordings are assumed to be simultaneous: c
//     aligns the span centres, sigma = half the difference of the span lengths. Usable only
//     when that sigma is small enough for the data (the calibration's latency scan) to finish.
//
// A match is "ambiguous" when a second minimum at least min_alias_separation_s away scores within
// alias_ratio of the best: then it is not trusted (found = false) and the message says why.
// The correction is to be ADDED to the pings' times: t_gps = t_ping + correction_s.
// Thread safety: reentrant.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "processor/survey/series.hpp"

namespace pitmap::proc::calib {

struct ClockSearchConfig {
    double scan_step_s = 0.5;              // coarse scan step over the whole overlap range
    double fine_window_s = 2.0;            // fine scan +- this around the coarse minimum
    double fine_step_s = 0.02;             // fine scan step
    int max_samples = 3000;                // aid samples used (evenly thinned)
    int max_coarse_samples = 500;          // ... of them in the scan over the whole overlap range
    double max_position_misfit_m = 10.0;   // median distance above which no match is claimed
    double max_attitude_misfit_deg = 3.0;  // RMS attitude difference above which ditto
    double alias_ratio = 1.5;              // second minimum within this factor = ambiguous
    double min_alias_separation_s = 3.0;   // minima closer than this are the same one
    double min_overlap_fraction = 0.5;     // of the aid samples inside the nav span
    // NMEA fix to topside: a fix shows in the first ping after it arrives, so it is this
    // latency plus half a ping interval old on average (subtracted); its spread is the sigma.
    double assumed_fix_latency_s = 0.1;
    double fix_latency_sigma_s = 0.1;
    // INS -> GNSS antenna, vehicle FRD (m): the NMEA position is the antenna's.
    Eigen::Vector3d antenna_lever_arm_m = Eigen::Vector3d::Zero();
};

struct ClockEstimate {
    bool found = false;
    std::string method;       // "header position", "header attitude", "span" or "none"
    double correction_s = 0;  // add to the ping times
    double sigma_s = 0;       // 1 sigma, including the staleness of the aids
    double misfit = 0;        // median distance (m) or RMS attitude difference (deg) at the best
    double alias_misfit = 0;  // best score at least min_alias_separation_s away (0 = none)
    double alias_correction_s = 0;
    std::int64_t samples = 0;  // aid samples used
    std::string message;       // one line for the terminal and the report
};

// `pings` and `nav` as ingest made them (GPS-time nav, pings on their own clock).
ClockEstimate EstimateSonarClock(const survey::PingSeries& pings,
                                 const survey::NavSeries& nav,
                                 const ClockSearchConfig& config = {});

// The sonar clock's rate. A PC clock runs tens of ppm fast or slow (35 ppm is 7 ms over a
// 200 s calibration window and 126 ms over an hour), which one offset cannot follow: on the
// quarry's 83P files the boresight's pitch came out 0.04 deg off from it, and the soundings of
// one window resolve the rate only to some 30 ppm. The head's own roll/pitch sensor is sampled
// at every interrogation on that clock (PingHeader::aid_attitude_at_ping), so matching it to
// the INS attitude along the whole survey times the clock at every ping. Gauss-Newton on
//   r_i = a_head(t_i) - a_ins(t_i + d + rate (t_i - t_mid)) - bias_a,   a = roll, pitch,
// with the INS attitude composed with the nominal mount, one bias per axis (the boresight, the
// sensor's own alignment), t_mid the middle of the pings, Cauchy weights (scale: the larger of
// cauchy_scale_deg and 2.5 robust sigmas) against glitches, started from a scan of d. The
// sigmas are the fit's, its residual sigma robust (MAD) and inflated for the residuals'
// correlation from ping to ping (AR(1)). A prior of rate_prior_sigma_ppm (what PC crystals do)
// keeps a short survey's rate from following the noise; the rate is used (found) when the data
// have at least halved that sigma (max_rate_sigma_ppm), the fit is good and the rate plausible.
// d (what the coarse match left plus the sensor's own lag) is reported only: the soundings
// find the latency in the calibration.
struct ClockRateConfig {
    double min_span_s = 60;  // of pings with the head's attitude
    std::int64_t min_samples = 300;
    std::int64_t max_samples = 20000;  // evenly thinned beyond
    double scan_s = 0.5;               // d scanned over +- this first (the coarse sigma)
    double scan_step_s = 0.01;
    double cauchy_scale_deg = 0.2;
    int max_iterations = 10;
    double rate_prior_sigma_ppm = 50;   // around 0, 1 sigma
    double max_rate_sigma_ppm = 25;     // less certain: not used, and said
    double max_abs_rate_ppm = 1000;     // beyond any crystal: a misfit, not a clock
    double max_residual_rms_deg = 1.0;  // the head's attitude does not follow the INS: not used
    // R_vehicle_sonar of the nominal mount: the head's attitude is the INS's composed with it.
    Eigen::Matrix3d R_vehicle_sonar = Eigen::Matrix3d::Identity();
};

struct ClockRateEstimate {
    bool found = false;
    double rate_ppm = 0;  // the ping times gain rate_ppm * 1e-6 * (t - reference_utime)
    double rate_sigma_ppm = 0;
    double offset_s = 0;  // d: add to the ping times at the reference (not applied)
    double offset_sigma_s = 0;
    std::int64_t reference_utime = 0;  // t_mid, on the pings' clock
    std::int64_t samples = 0;
    double residual_rms_deg = 0;  // after the fit (roll and pitch together)
    std::string message;
};

// `pings` on GPS time to within the scan (after the coarse correction or a configured offset).
ClockRateEstimate EstimateSonarClockRate(const survey::PingSeries& pings,
                                         const survey::NavSeries& nav,
                                         const ClockRateConfig& config = {});

// Steps of the topside clock (an NTP correction or a user setting the PC's time mid-survey):
// one offset cannot serve both sides. A step shows in the header times as an interval between
// consecutive pings (by ping number) that differs from the ping rate by more than
// min_jump_s; so does a pause of the pinging. The two are told apart by the aids: the pings
// between candidate jumps are segments, and each segment's own offset against the INS is
// scanned over +- scan_s around the coarse correction (the head's roll/pitch against the INS
// attitude composed with the mount, de-biased; else the header positions' median distance).
// Segments whose offsets differ by more than max(min_step_s, 4 sigma) are on different clocks:
// a step, and each segment is shifted onto the longest one's clock (ApplyClockSteps); equal
// offsets were a pause. A jump the aids cannot resolve (too few aids in a segment) is listed as
// unresolved. Header times that run backwards (the clock set back: pings before and after the
// step interleave, by ping number) cannot be ordered: `backward` > 0.
// `pings` on GPS time to within scan_s (after the coarse correction).
struct ClockStepConfig {
    double min_jump_s = 0.25;  // interval beyond the ping rate: a candidate
    double scan_s = 3.0;       // each segment's offset is scanned over +- this
    double scan_step_s = 0.02;
    double min_step_s = 0.1;            // offsets differing less: one clock
    std::int64_t min_aid_samples = 30;  // per segment, to resolve its offset
    int max_candidates = 20;            // largest jumps examined
    Eigen::Matrix3d R_vehicle_sonar = Eigen::Matrix3d::Identity();
    Eigen::Vector3d antenna_lever_arm_m = Eigen::Vector3d::Zero();
};

struct ClockStep {
    std::size_t ping_index = 0;  // first ping on the new clock (sorted pings)
    std::int64_t ping_number = 0;
    std::int64_t utime = 0;  // its time (GPS after the coarse correction)
    double jump_s = 0;       // what the header times jumped beyond the ping rate
    double step_s = 0;       // the clock's step measured by the aids (> 0: ahead afterwards)
    double sigma_s = 0;
    bool resolved = false;  // the aids resolved the segments on both sides
};

struct ClockStepResult {
    std::vector<ClockStep> steps;  // confirmed steps, and unresolved jumps (resolved = false)
    std::int64_t pauses = 0;       // jumps both sides of which share one clock
    std::int64_t backward = 0;     // pings whose number runs back in time
    // Per segment between steps: add to its ping times to put it on the reference clock.
    std::vector<std::pair<std::size_t, double>> segment_shift_s;  // (first ping, shift)
    std::string method;   // "header attitude" or "header position"
    std::string message;  // one line
};

ClockStepResult FindSonarClockSteps(const survey::PingSeries& pings,
                                    const survey::NavSeries& nav,
                                    const ClockStepConfig& config = {});
// Shifts each segment of confirmed steps onto the reference clock.
void ApplyClockSteps(survey::PingSeries& pings, const ClockStepResult& steps);

// The median distance (m) between the header positions and the INS antenna with `correction_s`
// added to the ping times (the fixes' mean age taken into account as EstimateSonarClock does);
// +inf when the headers carry no positions or too few fall in the navigation span.
double HeaderPositionMisfit(const survey::PingSeries& pings,
                            const survey::NavSeries& nav,
                            double correction_s,
                            const ClockSearchConfig& config = {});

// "a .. b GPS s (n s)" of a time span in microseconds, for messages naming spans.
std::string SpanText(std::int64_t first_utime, std::int64_t last_utime);

}  // namespace pitmap::proc::calib
