// SPDX-License-Identifier: MIT
// The INS's slow horizontal error, stated from the data (docs/decisions/027).
//
// Where GNSS is good an INS reports the steady sigma of its filter (about 1 cm for RTK), and its
// error is a time-correlated draw (a Gauss-Markov error with a correlation time of a minute): a
// 12-minute survey holds only a dozen independent draws of it, and one survey's draw can sit 1.5
// sigma off for minutes. SLAM cannot see it: every pass over the same ground shares it, and a
// part common to the whole survey moves every pass alike. The topside program writes the last
// fix of its own NMEA feed into every 83P header (survey::PingHeader::aid_latitude_deg): a GNSS
// position whose error is independent of the INS's filter. Their difference at each new fix,
// INS antenna position minus fix, is the INS's error minus the fix's.
//
// Only the ACROSS-TRACK component is used: a fix is stale by the serial latency and up to a ping
// interval (an unknown 0.1-0.3 s, 15-45 cm along the track at survey speed), which moves it along
// the velocity only. Per fix, the across-track innovation a_i = (p_ins_antenna - p_fix) . u_i,
// u_i the horizontal unit normal of the INS's velocity, the INS antenna taken at the fix's epoch:
// the ping time less the fixes' age, found by a scan (0..max_fix_age_s) for the age whose
// along-track innovations have the smallest median square (so the antenna's wave motion over the
// age does not enter). It holds the slow error along u_i and the fixes' own fast part (receiver
// noise, the header's 1e-5 minute rounding, the INS output's white noise, the age's jitter:
// 3.2-3.4 cm RMS on the simulator's surveys, more than the slow part), which decorrelates within
// seconds while the slow error holds for a minute. So
// the slow error's mean square is the mean product of two fixes of one straight stretch
// (course within max_course_change_deg) min_lag_s..max_lag_s apart:
//   sigma_slow^2 = mean(a_i a_j),  2 s <= t_j - t_i <= 10 s
// (its correlation exp(-lag / tau) is 0.85-0.97 for a minute's correlation time: the estimate
// is low by under 8 % in sigma). The fast part is the rest of the mean square. (The first form,
// the mean square less half the consecutive fixes' difference variance, took 1.2 times a wave
// period's motion for white noise: gps-outage seed 7 came out with no slow error at all.)
// For a horizontally isotropic error (the same per axis, as INSSTDEV reports it) the mean square
// along the across-track direction is the per-axis mean square, whatever the headings; the
// survey's passes in several headings sample both axes. sigma_slow is this survey's root mean
// square of the INS error over its GNSS-good time: the error's own realisation, which is what
// a stated sigma must contain. The mean is over the survey, not per window: one pass's fixes see
// one axis only.
//
// Limits (stated in decision 027): the fixes must come from a receiver whose error is
// independent of the INS's (a separate antenna, or the same receiver's raw fix before the
// filter); where the INS and the NMEA feed share one RTK solution, their common error cancels in
// the innovation and the estimate is low (the INS's own report stays the floor where it is used).
// An error in the antenna's across-track lever arm adds its square (conservative).
// Thread safety: reentrant.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <limits>
#include <string>
#include <vector>

#include "processor/survey/series.hpp"

namespace pitmap::proc::calib {

struct InsSlowErrorConfig {
    // INS -> GNSS antenna whose fixes the headers carry, vehicle FRD (m).
    Eigen::Vector3d antenna_lever_arm_m = Eigen::Vector3d::Zero();
    // Fixes where the INS reports a horizontal sigma at most this many times its smallest of
    // the survey: GNSS good (an outage's drift and the recovery after it are not the slow error).
    double good_sigma_ratio = 1.5;
    // After the INS's sigma was above good_sigma_ratio, its fixes count only this long after it
    // fell back (the filter pulls its drift back over seconds), s.
    double recovery_s = 30.0;
    double max_fix_age_s = 1.0;         // the fixes' age is found by a scan up to this, s
    double min_speed_mps = 0.3;         // below: no direction of motion
    double max_turn_rate_deg_s = 10.0;  // above: a stale fix is off the track's line, not along it
    double min_lag_s = 2.0;             // two fixes' products: at least this far apart, s
    double max_lag_s = 10.0;            // ... and at most this, s
    double max_course_change_deg = 10;  // ... on one straight stretch
    // Innovations (and differences) beyond this many robust sigmas (from the median square)
    // are dropped.
    double outlier_sigmas = 6.0;
    std::size_t min_fixes = 100;     // fewer usable fixes: not estimated
    std::size_t min_products = 200;  // ... or fewer pairs of fixes

    std::vector<std::string> Validate() const;
};

// One fix's across-track innovation (m) at its time (s, any origin).
struct AcrossInnovation {
    double t_s = 0;
    double across_m = 0;
    double course_rad = 0;  // of the motion, from north clockwise
};

struct InsSlowError {
    bool estimated = false;
    std::string message;            // what was estimated, or why not
    std::size_t fixes = 0;          // innovations used
    std::size_t fixes_dropped = 0;  // beyond outlier_sigmas
    std::size_t differences = 0;    // pairs of fixes whose products gave the slow part
    double rms_m = std::numeric_limits<double>::quiet_NaN();          // of the innovations
    double white_sigma_m = std::numeric_limits<double>::quiet_NaN();  // the fixes' fast part
    // Per horizontal axis: the RMS of the INS's slow error over the survey's GNSS-good time.
    double slow_sigma_m = std::numeric_limits<double>::quiet_NaN();
    // The INS's own smallest horizontal sigma per axis (its GNSS-good report), for comparison.
    double reported_sigma_m = std::numeric_limits<double>::quiet_NaN();
};

// The estimate from innovations in time order (the maths above; reported_sigma_m not set).
InsSlowError SlowErrorFromInnovations(const std::vector<AcrossInnovation>& a,
                                      const InsSlowErrorConfig& config = {});

// The across-track innovations of the header fixes against the INS antenna (pings on the GPS
// clock: after the sonar clock is known), GNSS-good fixes only.
std::vector<AcrossInnovation> HeaderFixInnovations(const survey::PingSeries& pings,
                                                   const survey::NavSeries& nav,
                                                   const InsSlowErrorConfig& config,
                                                   double* reported_sigma_m = nullptr);

// Both: the estimate of one survey; not estimated (with the reason) without header fixes or
// INS standard deviations.
InsSlowError EstimateInsSlowError(const survey::PingSeries& pings,
                                  const survey::NavSeries& nav,
                                  const InsSlowErrorConfig& config = {});

}  // namespace pitmap::proc::calib
