// SPDX-License-Identifier: MIT
// Boresight calibration after the seed paper's §4.1: on a short low-drift segment with
// overlapping passes, split the trajectory into parts, pair each sounding with its closest
// sounding of another part (k-d tree, nanoflann), and find the roll/pitch/yaw of
// R_vehicle_sonar that minimises the point-to-plane distances (Gauss-Newton with a Cauchy
// kernel, correspondences re-found every outer iteration). Verified on other segments.
//
// Model: p = t_wv + R_wv (lever + R_vs(theta) s), s = the beam's sonar-frame vector. With the
// right perturbation R_vs Exp(delta): dp/d delta = -R_wv R_vs [s]x. The residual of a pair
// (p from part a, q from part b) is r = n_p . (p - q), n_p the normal of p's own part (PCA of
// its neighbours within normal_radius_m), so dr/d delta = n_p^T (-A_p [s_p]x + A_q [s_q]x),
// A = R_wv R_vs.
// Unknowns besides the boresight: a position correction per node (one every part_duration_s,
// linear in between; priors height_offset_sigma_m and horizontal_offset_sigma_m, chained as a
// Gauss-Markov process of offset_correlation_time_s): the INS error differs between passes and
// would otherwise bias roll (parallel passes see a roll error only as a height step) and pitch
// (an along-track shift). On six seeds of the quarry, the demo and bejanca the horizontal terms
// took the mean boresight error from 0.062 to 0.039 deg and the worst from 0.141 to 0.075 deg,
// and made the formal sd honest (pitch: 0.011 claimed, 0.07 found; now 0.025 against 0.027).
// The stated uncertainty (sd_deg) adds to the fit's formal sd the INS attitude error that a
// window cannot tell from the mount: the INS's reported 1-sigma averaged over the window as a
// Gauss-Markov error (on eight surveys the errors were then -2.0..+2.1 sd, RMS 1.13).
// Pairs are weighted by 1 / (sigma_p^2 + sigma_q^2), sigma = fraction * range + constant.
// Latency (estimate_latency): the sonar's time offset tau is a fourth unknown, the automatic
// patch test's "latency": p(t + tau), dp/dtau from the INS poses at t + tau +- 5 ms, so the pair
// Jacobian gains n_p . (dp_p/dtau - dp_q/dtau). It is observable through the vehicle's rotation
// rate (wave roll and pitch, turns) and, on slopes, its speed. Starting values further than the
// linear range (about a tenth of the roll period) need latency_scan_s: the residual RMS is first
// scanned over initial +- latency_scan_s in latency_scan_step_s at the nominal mount.
// Segment choice (when not given): windows of segment_duration_s, stepped by a quarter; a
// window is eligible when its INS 1-sigma horizontal position and heading stay under the limits
// (low drift); among those the one with the most overlap (1 m cells seen by parts at least
// min_separation_s apart) wins. When no window is low drift, windows of half and then a quarter
// of the length are tried before the best drifting window is taken.
// Thread safety: reentrant. Results do not depend on the thread count.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "common/progress.hpp"
#include "processor/georef/georef.hpp"

namespace pitmap::proc::calib {

struct BoresightConfig {
    double segment_start_s = -1;      // GPS seconds; < 0 = choose automatically
    double segment_duration_s = 300;  // seconds (clamped to the survey)
    double part_duration_s = 10;      // trajectory parts, seconds
    double min_separation_s = 20;     // pairs only between soundings this far apart in time
    int beam_stride = 4;              // use every n-th sounding of a ping
    double max_distance_m = 1.0;      // correspondence distance, first iteration
    double min_distance_m = 0.3;      // ... shrinking to this by the last iteration
    double normal_radius_m = 0.6;     // neighbourhood for the normals
    double cauchy_scale_m = 0.05;     // robust kernel scale
    int max_iterations = 7;           // outer (correspondence) iterations
    // Extrapolate the rotation (and the latency) along steps that agree in direction
    // (accelerated ICP, Besl & McKay 1992): 7 iterations reach what 12 plain ones did (bejanca
    // boresight error 0.0335 against 0.0332 deg, residual 0.05625 against 0.05642 m).
    bool accelerate = true;
    double convergence_deg = 1e-4;        // stop when the update is smaller
    double max_position_stddev_m = 0.15;  // low-drift limit (horizontal, 1 sigma)
    double max_heading_stddev_deg = 0.2;  // low-drift limit
    int num_verify_segments = 2;          // other segments to verify on
    // On the verification segments pairs are sought from every n-th sample only; the points
    // they pair with (and the normals' neighbourhoods) stay every beam_stride-th sounding, so
    // the pairs are an unbiased subsample of the full set. Verification only compares residual
    // RMS (before / after, and the latency gate's 2 %), and its two segments, each indexed and
    // searched three times, were about 45 % of the stage's searches.
    int verify_query_every = 2;
    bool estimate_height_offsets = true;  // per-node INS height corrections (nuisance)
    double height_offset_sigma_m = 0.03;  // their prior, 1 sigma
    // Horizontal ones too: the INS's horizontal error (RTK/INS: ~1 cm) differs between passes,
    // and over 5 m of water 1 cm along track reads as 0.1 deg of pitch (and, at one speed, as
    // 7 ms of latency). The pitch stays observable from how the shift grows with slant range.
    bool estimate_horizontal_offsets = true;
    double horizontal_offset_sigma_m = 0.01;  // their prior, 1 sigma
    // The node corrections follow the INS error's own correlation (Gauss-Markov: o_k - phi
    // o_(k-1) with phi = exp(-part_duration_s / this), the first node absolute); 0 = independent.
    double offset_correlation_time_s = 120;
    // Correlation time of the INS's attitude error, for the boresight's stated uncertainty: over a
    // window much shorter than it the INS's error passes into the mount whole (0 = white: it
    // averages out).
    double ins_attitude_correlation_time_s = 120;
    double range_noise_fraction = 0.002;   // pair weight 1/sigma^2, sigma = fraction * range
    double range_noise_constant_m = 0.02;  //   + constant, per sounding
    bool estimate_latency = true;          // the sonar time offset as a fourth unknown
    double initial_latency_s = 0;          // start value (a coarse clock estimate's rest)
    double latency_scan_s = 0;             // scan +- this first; 0 = no scan
    double latency_scan_step_s = 0.05;
    double latency_sigma_s = 1.0;  // prior on (tau - initial), 1 sigma

    std::vector<std::string> Validate() const;
};

struct SegmentScore {
    double start_s = 0, end_s = 0;  // GPS seconds
    std::int64_t overlap_cells = 0;
    double max_position_stddev_m = 0, max_heading_stddev_deg = 0;
    bool low_drift = false;
};

struct ResidualStats {
    std::int64_t pairs = 0;
    double rms_m = 0;  // RMS point-to-plane distance over pairs within the gate
    double median_abs_m = 0;
    double expected_rms_m = 0;  // what the range noise alone would leave (pair weights)
};

struct VerifyResult {
    SegmentScore segment;
    ResidualStats before, after;  // nominal mount and latency; calibrated mount and latency
    // Calibrated mount at the nominal latency (only when the latency was estimated): a latency
    // that fits its own window but not this one (a sonar clock that stepped) shows here, even
    // where the calibrated boresight makes `after` better than `before`.
    ResidualStats after_nominal_latency;
};

enum class Termination { kConverged = 0, kMaxIterations, kNoOverlap, kCancelled };
const char* ToString(Termination t);

struct BoresightResult {
    survey::SonarMount mount;          // the input mount with the calibrated boresight
    SegmentScore segment;              // the one used
    ResidualStats before, after;       // on that segment
    std::vector<VerifyResult> verify;  // other segments
    int iterations = 0;
    double formal_sd_deg[3] = {0, 0, 0};  // roll, pitch, yaw (range noise only: optimistic)
    // The INS attitude error the boresight takes in: the average over the window of an error
    // the INS reports (its roll, pitch and heading 1-sigma) and that wanders with correlation
    // time ins_attitude_correlation_time_s; a calibration cannot tell it from the mount.
    double ins_attitude_sd_deg[3] = {0, 0, 0};
    bool ins_attitude_reported = false;  // the INS gave roll, pitch and heading sigmas
    double sd_deg[3] = {0, 0, 0};        // both together, 1 sigma
    double height_offsets_rms_m = 0;     // RMS of the estimated height corrections
    bool latency_estimated = false;
    double latency_s = 0;            // add to the ping times (t_gps = t_ping + latency_s)
    double latency_formal_sd_s = 0;  // range noise only: optimistic
    double latency_scan_best_s = 0;  // the scan's minimum (when scanned)
    // The last latency step hit its cap (latency_scan_step_s): the latency was still running
    // when the iterations ended, i.e. the clock is off by more than the data resolved.
    bool latency_unresolved = false;
    Termination termination = Termination::kNoOverlap;
    std::vector<SegmentScore> candidates;
    std::string message;
};

// `geo` must have been georeferenced with `mount`; its points and pings are read only.
BoresightResult CalibrateBoresight(const georef::GeorefResult& geo,
                                   const survey::NavSeries& nav,
                                   const survey::SonarMount& mount,
                                   const BoresightConfig& config,
                                   const ProgressCallback& progress = {});

}  // namespace pitmap::proc::calib
