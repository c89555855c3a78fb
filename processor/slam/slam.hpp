// SPDX-License-Identifier: MIT
// Continuous-time (semi-rigid) SLAM for multibeam slices, after Elseberg, Borrmann & Nuechter
// (2013) and Borrmann et al. (2008); seed paper section 4.2.
//
// Input: one Slice per ping (initial pose from the INS, soundings in the vehicle frame).
// Two stages, both Gauss-Newton on the sparse normal equations solved with CHOLMOD:
//  0. Coarse search (GNSS outages): sections whose INS horizontal sigma is large are placed by a
//     horizontal offset search against a height grid of the sections the INS is sure about; the
//     offsets of a run of such sections are chosen together under the INS drift model (a
//     least-squares smoother over each section's fit surface); see coarse_search_m.
//     GNSS recoveries (the reported sigma falls sharply) start a new section and bin, and the
//     sections after one are short (1, 1, 2, 4, 8 s): the INS pulls its drift back within
//     seconds there.
//  1. Rigid: the trajectory is split into sections of section_length_s; sections whose points
//     overlap (at least min_section_link_pairs closest-point pairs) are linked; all section
//     corrections are solved at once (globally consistent scan matching) and correspondences
//     are found again each iteration, like ICP, coarse to fine. By default the corrections sit
//     at the section centres and are interpolated in time between them.
//  2. Semi-rigid: one 6-DoF pose per bin of bin_slices slices (slice poses interpolated inside
//     a bin); point pairs only between slices at least min_time_separation_s apart and closer
//     than max_pair_distance_m; relative-motion terms between consecutive poses keep the motion
//     the INS measured, weighted by the INS's own 1-sigma; optional absolute terms. Each step
//     is solved by overlapping windows in time over a coarse level (semi_rigid_window_s) on
//     surveys longer than two windows, so the factorisation does not hold the whole survey.
// INS terms in both stages: relative motion (sigma from the steady INS sigma and from its
// growth), a drift-smoothness term (the velocity error is a random walk) and absolute terms; the
// reported sigma is not believed to shrink faster than ins_sigma_recovery_time_s.
// Guards ("must not get worse"): a step is taken only if it lowers the total cost (INS terms and
// robust pair terms) on the pairs it was computed from, else the Levenberg damping grows; the
// pair score of every iterate (closest-point distance over the overlap, truncated at
// max_pair_distance_m, RMS) is measured, a stage stops after score_patience iterations without
// a better one, and its last iterate is kept unless its score is worse than the best iterate's
// by more than score_tolerance (then the best one is). A plane-fit consistency score (vertical RMS
// over grid cells seen by passes at least min_time_separation_s apart) is reported too; it is
// no stopping criterion, since multi-metre drift can make it rise while the alignment improves.
//
// World frame: local ENU (z up). Vehicle frame: FRD. Rotations are optimised on the manifold
// (processor/slam/slam_math.hpp).
//
// THREADING: RunSlam uses TBB (num_threads, 0 = TBB's default) for the k-d trees, the
// closest-point search and the normal equations.
// @note Sums over pairs are reduced in thread-dependent order, so results depend on the
//       thread count at the level of floating-point rounding (compare with a tolerance).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "processor/registration/correspondence.hpp"
#include "processor/slam/slam_math.hpp"

namespace pitmap::proc::slam {

// One sonar ping, ready for SLAM.
struct Slice {
    double gps_time_s = 0;  // GPS time of the ping, seconds
    Eigen::Isometry3d T_world_vehicle = Eigen::Isometry3d::Identity();  // initial, from the INS
    // Soundings of this ping already in the vehicle frame (lever arm and boresight applied), m.
    std::vector<Eigen::Vector3f> points_vehicle;
    // INS 1-sigma: roll, pitch, yaw (rad), east, north, up (m).
    Eigen::Matrix<double, 6, 1> pose_sigma = Eigen::Matrix<double, 6, 1>::Constant(0.01);
};

// Correspondence types (point-to-point, point-to-plane, GICP): the registration core's.
using reg::CorrespondenceType;

inline constexpr int kMaxNormalNeighbours = 64;  // SlamConfig::normal_neighbours bound

struct SlamConfig {
    double min_time_separation_s = 30.0;  // t_d: pairs only between slices this far apart
    double max_pair_distance_m = 0.5;     // d_max: closest-point pairs closer than this
    // Pairs of a query point only with the passes over its cell (2 m) nearest in time: this many
    // before it and this many after it, among those at least t_d away (0 = every pass, the seed
    // paper: the cost then grows with the square of the survey's duration over a fixed pit).
    // docs/decisions/015.
    int max_partner_passes = 2;
    double section_length_s = 15.0;  // rigid sections and k-d tree blocks, seconds
    // Rigid stage iterations (0: skip the stage): after an outage the stage creeps a few cm per
    // iteration along weakly constrained walls, so more iterations recover more drift for more
    // time; with good GNSS it stops early (score_patience). docs/decisions/005.
    int rigid_iterations = 30;
    // Rigid stage pair distance at most, shrunk geometrically to max_pair_distance_m over its
    // iterations (coarse to fine); the first is 3 x the largest section median INS horizontal
    // sigma, within [max_pair_distance_m, this]. Longer reaches further but drags sections
    // along smooth terrain (multi-metre drift is the coarse search's job). docs/decisions/005.
    double rigid_max_pair_distance_m = 1.0;
    int min_section_link_pairs = 50;  // pairs needed to link two sections (rigid graph)
    // Rigid stage: true = one correction per section centre, slices interpolated in time between
    // centres (continuous track; the INS drift is smooth); false = each section moves rigidly,
    // rotating about its mean position (the paper).
    bool rigid_interpolate_sections = true;
    // Coarse horizontal search before the rigid stage, for sections whose INS horizontal
    // 1-sigma exceeds coarse_search_min_sigma_m (GNSS outages): the offset within
    // min(coarse_search_m, 3 sigma) that best fits the section to a height grid (cells of
    // coarse_search_cell_m) of the other sections; 0 = off.
    double coarse_search_m = 12.0;
    double coarse_search_step_m = 0.5;
    double coarse_search_cell_m = 4.0;
    double coarse_search_min_sigma_m = 0.5;
    // Semi-rigid: slices per pose (1 = one pose per slice). The factorisation cost grows fast
    // with the pose count when passes overlap widely; 10 (1 s at 10 Hz) keeps it small.
    int bin_slices = 10;
    int max_iterations = 15;  // semi-rigid stage iterations
    // Semi-rigid stage: its normal equations (and the posterior's) are solved in overlapping
    // windows of the survey in time, so that no factorisation holds the whole survey
    // (docs/decisions/017): each Gauss-Newton step is one forward sweep of a restricted
    // multiplicative Schwarz method (block Gauss-Seidel over the windows, each solved with the
    // corrections outside it held at the sweep's latest values, its core's corrections kept);
    // the sweeps alternate between two sets of cores offset by half a core, so that no window
    // boundary stays one. The survey is cut into floor(duration / semi_rigid_window_s) cores
    // (at least 1: a survey shorter than twice this is one system, as before); each window
    // reaches semi_rigid_window_overlap_s past its core on both sides. 0 = one system always
    // (the factor then grows faster than the survey: docs/decisions/015).
    double semi_rigid_window_s = 600.0;
    double semi_rigid_window_overlap_s = 120.0;
    // The windows' coarse level: one node every this many seconds, node corrections
    // interpolated between them; 0 = a tenth of the window length, at least section_length_s
    // (60 s by default). It is one system over the whole survey, so it is kept coarse enough
    // to stay small: at 15 s (decision 017) it fills like the rigid stage's whole system
    // (docs/decisions/021).
    double semi_rigid_window_coarse_s = 0.0;
    // The rigid stage by the same windows over a coarse level (docs/decisions/021): its
    // whole-survey system (one node per section) fills like the semi-rigid one, with the square
    // of the passes over the pit (0.07, 0.28, 0.95 M nonzeros at 1x, 2x, 4x bejanca). Cut into
    // floor(duration / rigid_window_s) cores (a survey shorter than twice this is one system),
    // each window reaching rigid_window_overlap_s past its core, over a coarse level of one
    // node every rigid_window_coarse_s (0 = a tenth of the window, at least
    // section_length_s). 0 = one system always.
    double rigid_window_s = 600.0;
    double rigid_window_overlap_s = 120.0;
    double rigid_window_coarse_s = 0.0;
    // Converged when the largest pose update is below both thresholds.
    double convergence_rotation_rad = 2e-5;
    double convergence_translation_m = 2e-4;
    CorrespondenceType correspondence = CorrespondenceType::kGicp;
    int normal_neighbours = 24;   // neighbours for normals / covariances, 3..kMaxNormalNeighbours
    double point_sigma_m = 0.05;  // 1-sigma of a point along the surface normal
    // GICP: 1-sigma along the surface (plane-like C). A pair's offset along the surface is
    // mostly where the other pass's nearest sounding happens to lie; looser frees the
    // along-track position the soundings cannot see (outage drift recovered) for a few tenths
    // of a mm on surveys whose INS is good. docs/decisions/002.
    double gicp_tangent_sigma_m = 3.0;
    // Down-weights wrong pairs (other surfaces within d_max, clutter). docs/decisions/009.
    RobustKernel robust_kernel = RobustKernel::kHuber;
    double robust_width = 2.0;  // kernel width, in point sigmas
    int query_stride = 16;      // every n-th point of a slice (of those kept) is a query point
    // The points each pass contributes, bounded per cell (docs/decisions/036): per section
    // (section_length_s of pings, one pass over a cell) and per cube of pass_cell_m in the world
    // frame by the INS poses, only the first pass_cell_points points (in time order) enter SLAM.
    // A pass's surface is then sampled at the cube's size however dense the sonar, so SLAM's
    // points, world points and k-d trees hold a bounded count per pass over a cell, not the
    // sonar's every sounding. 0 = every point (as before: a survey whose cubes hold at most
    // pass_cell_points of a section's points gives the same run either way).
    double pass_cell_m = 0.0;
    int pass_cell_points = 1;
    // A section where the INS's horizontal 1-sigma (the larger of east and north, as the coarse
    // search reads it) exceeds this at any slice keeps every point: in a GNSS outage the drift
    // is stated by the perturbed-start runs' spread, which the thinned points narrowed below the
    // true error (docs/decisions/046, 048). 0 = every section bounded.
    double pass_cell_max_sigma_m = 0.0;
    // INS relative-motion terms between consecutive poses i, j: per component the sigma of the
    // motion over dt is sqrt(f^2 * 2 dt / ins_correlation_time_s (at most 1) + (g_j - g_i)^2)
    // * ins_sigma_scale, with f the survey's smallest sigma (a first-order Gauss-Markov error)
    // and g = sqrt(sigma^2 - f^2) the part that grows in an outage; at least the floors below.
    // World rotation x, y use max(roll, pitch), z uses yaw; translation x, y (slice frame)
    // max(east, north), z up.
    double ins_correlation_time_s = 60.0;
    double ins_sigma_scale = 1.0;
    double min_relative_rotation_sigma_rad = 2e-5;
    double min_relative_translation_sigma_m = 5e-4;
    // The INS's reported 1-sigma is not believed to shrink faster than exp(-dt / this): a
    // filter that regains GNSS after an outage reports a small sigma at once but pulls its
    // drift back over seconds, so sigma_i = max(reported_i, sigma_{i-1} exp(-dt / this)),
    // per component. 0 = take the reported sigma as it is.
    double ins_sigma_recovery_time_s = 3.0;
    // Smoothness of the INS position error: its rate (the velocity error) follows a random walk
    // of this density, as dead reckoning does in a GNSS outage; the term ties the corrections
    // of consecutive poses so that matches at turns and pit walls carry along straight lines.
    // Loosened where the INS sigma falls. 0 = off.
    double drift_velocity_random_walk_mps_per_sqrt_s = 0.003;
    // In a GNSS outage the INS's position error is one realisation of a dead-reckoning drift
    // (an integrated random walk), which the drift-smoothness term and the poses before the
    // outage state; the relative-motion and absolute position terms model errors independent
    // per step and per pose, which only the steady (Gauss-Markov) part is. true = their
    // position information is scaled by the steady part's share of the variance,
    // f^2 / (f^2 + g^2) (g the growing part, f the survey's smallest sigma): unchanged where
    // GNSS is good, negligible tens of seconds into an outage. false = counted in full, which
    // pulls the optimum towards the INS along the track (docs/decisions/022).
    bool drift_by_smoothness_only = true;
    bool absolute_position_terms = true;  // GNSS/INS position per pose, weighted by its sigma
    bool absolute_attitude_terms = true;  // INS attitude per pose, weighted by its sigma
    // The absolute terms' sigmas are the INS's with their steady part (the survey's smallest
    // sigma, what the INS holds with GNSS) times this; the part above it (an outage's drift) is
    // as reported. Smaller holds passes whose INS was good against the thousands of pair terms
    // that pull them onto the passes they overlap, at a little of the pairs' averaging.
    // docs/decisions/003.
    double absolute_sigma_scale = 0.4;
    double score_cell_m = 0.5;  // plane-fit consistency score grid cell (reported only)
    // Stop after this many iterations without a better pair score (the rigid stage: only once
    // its pair distance has come down to max_pair_distance_m).
    int score_patience = 2;
    double score_tolerance = 1e-3;  // a gain counts above this fraction; see the guards above
    int num_threads = 0;            // 0 = TBB default
    // Posterior of the semi-rigid result (SlamPosterior): computed after the stage when true,
    // with the perturbed-start runs (posterior_start_runs) the pose sigma the TPU takes
    // (docs/uncertainty.md, docs/decisions/016: gps-outage's true error within the stated 95 %
    // radius in 99 % of the pings). The normal equations cost 10-28 % of the stage.
    bool posterior = true;
    int posterior_batch_nodes = 50;  // nodes (6 right-hand sides each) per CHOLMOD solve
    // The cluster-robust (sandwich) covariance of SlamPosterior: the pair terms' information
    // from their residuals, clustered by section pair, instead of from their assumed weights
    // (the formal H^-1 treats ~10^5 correlated pairs as independent: sub-mm sigmas).
    bool posterior_cluster_robust = true;
    // Add the INS's steady sigma (the survey's smallest, per component) to every slice's
    // posterior: the reference SLAM is anchored to, common to the passes it aligns; and the
    // white noise of each INS position output, which the INS's sigma omits and SLAM's
    // one-second nodes leave in every ping (PositionWhiteNoise, docs/decisions/022).
    bool posterior_reference_sigma = true;
    // The INS's slow horizontal error per axis as the data states it (m; 0 = not known): the
    // pipeline sets it from the GNSS fixes in the ping headers (calib::EstimateInsSlowError,
    // docs/decisions/027). The reference term of the posterior then takes the larger of it and
    // the INS's own steady sigma for east and north. Not a setting: a measurement of the survey.
    double reference_horizontal_sigma_m = 0;
    // GICP pairs: true (the default) = the posterior takes their along-surface information as
    // the solver does (gicp_tangent_sigma_m); false = along their normal only (the offset along
    // a surface is where the other pass's nearest sounding lies). Measured on gps-outage
    // (docs/decisions/012): along the normal only, 78 % of the pings within the 95 % radius
    // against 88 % with it: the normals of a bench's edges and boulders tie the passes along
    // the track in the model, and the error SLAM leaves is elsewhere.
    bool posterior_tangent_information = true;
    // Without the cluster-robust part: scale the formal covariance H^-1 by the a-posteriori
    // variance factor sigma0^2 (see SlamPosterior); false = the formal covariance as it is.
    bool posterior_variance_factor = true;
    // SLAM runs from perturbed starts whose spread about this run's result is added to the
    // posterior (StartSpread; docs/decisions/016): each starts from the input poses moved by a
    // draw of the INS's outage drift (PerturbedStart), and where SLAM stops in a flat valley of
    // its cost along a weakly constrained track (the along-track local minima of an outage,
    // which the posterior about the optimum cannot state) the runs end apart. 0 = off; each run
    // costs about one SLAM run without the posterior; they are not made when the INS reports
    // no horizontal drift beyond point_sigma_m (a GNSS-good survey: the starts would not differ).
    int posterior_start_runs = 4;
    std::uint64_t posterior_start_seed = 1;  // seed of the runs' perturbations

    // Every problem with the configuration (empty when valid).
    std::vector<std::string> Validate() const;
};

enum class SlamStage { kRigid, kSemiRigid };

enum class SlamTermination {
    kConverged,      // pose updates below the thresholds
    kMaxIterations,  // iteration budget spent
    kScoreStalled,   // pair score did not improve for score_patience iterations
    kNoImprovement,  // no damped step lowered the cost on the current pairs
    kNoOverlap,      // no point pairs at all: the trajectory is returned unchanged
    kSolverFailed,   // the normal equations could not be factorised
    kCancelled,      // the progress callback returned false
    kInvalidInput,   // empty input, non-finite values or an invalid config
};
const char* ToString(SlamTermination t);

struct SlamIteration {
    SlamStage stage = SlamStage::kSemiRigid;
    int iteration = 0;          // 1-based within the stage
    std::size_t num_pairs = 0;  // point pairs used
    // What the pairs link (max_partner_passes bounds them for a fixed pit however long the
    // survey): distinct section pairs, the most sections one section is paired with, and the
    // off-diagonal 6x6 blocks of the normal equations (node pairs the terms couple).
    std::size_t num_section_pairs = 0;
    std::size_t max_section_partners = 0;
    std::size_t normal_equation_blocks = 0;
    // CHOLMOD's analysis of them: nonzeros of the Cholesky factor and flops of one factorisation
    // (windowed, SlamConfig::semi_rigid_window_s: the largest window's nonzeros, the factor held
    // at once, and the flops of one sweep over all windows).
    double factor_nonzeros = 0;
    double factor_flops = 0;
    std::size_t windows = 1;   // windows of the step's solve (1: the whole survey in one system)
    double cost = 0;           // total cost (robust, whitened) before the step
    double cost_after = 0;     // the same terms and pairs after the step (< cost if taken)
    int rejected_steps = 0;    // damped steps that did not lower the cost
    double damping = 0;        // Levenberg lambda of the step taken
    double pair_rms_m = 0;     // RMS pair distance before the step
    double pair_score_m = 0;   // pair score after the step (lower is better)
    double consistency_m = 0;  // plane-fit score after the step (reported only)
    double max_step_rotation_rad = 0;
    double max_step_translation_m = 0;
    bool best = false;  // this iterate has the best pair score so far
};

struct SlamPose {
    double gps_time_s = 0;
    Eigen::Isometry3d T_world_vehicle = Eigen::Isometry3d::Identity();
    std::size_t input_index = 0;  // index of the slice in the input
};

// One rigid section (section_length_s of slices) and what the coarse search did with it.
struct SlamSection {
    double t0_s = 0, t1_s = 0;  // GPS time of its first and last slice
    double sigma_h_m = 0;       // median INS horizontal 1-sigma over its slices
    bool searched = false;      // sigma_h_m > coarse_search_min_sigma_m
    bool shifted = false;       // searched and moved (by its own fit, or by its neighbours' if it
                                // did not overlap the trusted sections)
    Eigen::Vector3d coarse_offset_m = Eigen::Vector3d::Zero();  // world shift applied, ENU
};

// The uncertainty of the semi-rigid result (docs/uncertainty.md): the normal equations
// H = J^T W J of all terms (INS relative, drift-smoothness and absolute terms, and the robust
// pair terms with their final weights), linearised once more at the kept iterate without
// Levenberg damping; the marginal covariance of each pose node's correction is the node's
// diagonal 6x6 block of H^-1 (CHOLMOD solves with block right-hand sides), times the
// a-posteriori variance factor sigma0^2 = (sum of whitened squared residuals, the robust cost)
// / (observations - unknowns), when posterior_variance_factor. A slice's pose perturbation is
// the interpolation of its two nodes' (slam_math.hpp's world-frame perturbation, through
// NodeToSlice): C_s = A C_00 A^T + B C_11 B^T + A C_01 B^T + B C_10 A^T with the nodes'
// blocks and their cross block, A and B the weighted node-to-slice Jacobians. The rotation
// part is expressed as roll, pitch, yaw increments (the axes of hydro::SoundingCovariance:
// vehicle x, the horizontal axis across the heading, the vertical).
// The formal H^-1 (with or without sigma0^2) is far too confident: it takes the ~10^5 pair
// residuals as independent, while those of one overlap share the same surface, sonar and pose
// errors (measured on gps-outage: 0.4 mm stated, 0.15 m true in the outage; sigma0^2 = 0.03
// makes it worse). With posterior_cluster_robust (the default) the covariance is the
// cluster-robust sandwich H^-1 (H_ins + M) H^-1 (Liang & Zeger 1986) with M = sum_c g_c g_c^T,
// g_c = J_c^T W_c r_c the gradient of the pairs of cluster c (the pairs between one pair of
// rigid sections, section_length_s): the pairs' information as their residuals show it,
// correlated within a cluster, independent between clusters. The INS terms keep their
// model-based part, bounded above by H^-1 >= H^-1 H_ins H^-1 (H >= H_ins), so that
// C = H^-1 + H^-1 M H^-1 (conservative by at most H^-1 H_pairs H^-1).
struct SlamPosterior {
    bool computed = false;
    // As SlamResult::trajectory: 1-sigma roll, pitch, yaw (rad), east, north, up (m).
    std::vector<Vector6d> slice_sigma;
    double variance_factor = 0;    // sigma0^2 (applied only if posterior_variance_factor)
    double observations = 0;       // residual rows: 1 per pair for point-to-plane and GICP
    double unknowns = 0;           // 6 per node
    std::size_t num_pairs = 0;     // pairs of the final linearisation
    std::size_t nodes_solved = 0;  // nodes whose marginal blocks were solved
    // Windows of the posterior's normal equations (as the stage's, SlamConfig::
    // semi_rigid_window_s): each window's nodes get their marginals from the terms that lie
    // within the window alone (terms reaching outside it are left out: conservative, their
    // information is dropped), taken for the window's core; 1 = the whole survey.
    std::size_t windows = 1;
    double largest_factor_nonzeros = 0;  // the largest window's Cholesky factor
    std::size_t clusters = 0;            // pair clusters of the sandwich (0: formal covariance)
    // Intra-cluster correlation of the pairs' normal residuals; a cluster of n pairs informs
    // as n / (1 + (n - 1) rho) independent ones.
    double residual_correlation = 0;
    // Median over the slices of the formal horizontal sigma sqrt((sE^2 + sN^2) / 2) of H^-1
    // alone (no variance factor, no sandwich), for comparison.
    double formal_horizontal_median_m = 0;
    // The white noise of each INS position output (east, north, up, m; PositionWhiteNoise),
    // added to every slice with the steady sigma when posterior_reference_sigma.
    Eigen::Vector3d ins_white_noise_m = Eigen::Vector3d::Zero();
    // The reference's horizontal sigma per axis the posterior used (the larger of the INS's
    // steady sigma and SlamConfig::reference_horizontal_sigma_m), m.
    double reference_horizontal_sigma_m = 0;
    // How the INS's steady position error entered slice_sigma (decisions 042, 045): "whole"
    // (the result follows the INS), "rigid_response" (the result is the rigid stage's, and its
    // error from that process was propagated through the rigid stage's normal equations),
    // "semi_rigid_response" (a semi-rigid iterate was kept: the same through that stage's
    // equations, window by window), "none"; the median of that part's vertical sigma (the
    // responses only), and its time.
    std::string steady_model;
    double steady_up_median_m = 0;
    double steady_s = 0;
    // The perturbed-start runs (posterior_start_runs) whose spread was added to slice_sigma in
    // quadrature, and that spread alone per slice (1-sigma east, north, up, m; empty without).
    std::size_t start_runs = 0;
    std::vector<Eigen::Vector3d> start_spread;
    std::string start_runs_note;  // why the runs were not made, when they were not
    double search_s = 0, build_s = 0, factor_s = 0, marginals_s = 0, start_runs_s = 0, total_s = 0;
    std::string message;  // why it was not computed, when it was not
};

struct SlamTimings {
    double coarse_search_s = 0;
    double trees_s = 0;
    double search_s = 0;
    double build_s = 0;
    double solve_s = 0;
    double score_s = 0;
    double total_s = 0;
};

// What SLAM's own per-sounding arrays held when their sum was largest (bytes, capacities
// counted; sampled after each search of pairs, the stage's peak): SlamResult::memory.
struct SlamMemory {
    std::size_t points_bytes = 0;        // the slices' points in the vehicle frame, sorted
    std::size_t world_points_bytes = 0;  // ... moved to the world by the current iterate
    std::size_t trees_bytes = 0;         // the sections' k-d trees (index and nodes)
    std::size_t neighbour_bytes = 0;     // the sections' normal-fit neighbour tables
    std::size_t pairs_bytes = 0;         // one search's pairs
    std::size_t total_bytes = 0;         // their sum
};

struct SlamResult {
    std::vector<SlamPose> trajectory;  // corrected, one per slice, sorted by GPS time
    std::vector<SlamIteration> iterations;
    int rigid_iterations = 0;
    int semi_rigid_iterations = 0;
    std::size_t num_sections = 0;
    std::size_t num_section_links = 0;         // rigid graph edges
    std::size_t num_sections_searched = 0;     // coarse search: sections the INS was unsure of
    std::size_t num_sections_shifted = 0;      // ... that were moved (SlamSection::shifted)
    std::vector<SlamSection> sections;         // the rigid sections, in time order
    std::size_t num_poses = 0;                 // semi-rigid unknown poses
    std::size_t num_pairs = 0;                 // pairs of the last iteration
    std::size_t num_points_in = 0;             // finite points given
    std::size_t num_points = 0;                // ... of which SLAM used (SlamConfig::pass_cell_m)
    std::size_t num_sections_every_point = 0;  // sections left whole (pass_cell_max_sigma_m)
    double initial_consistency_m = 0;          // plane-fit score of the input trajectory
    double final_consistency_m = 0;            // ... and of the result
    // The result's plane residuals per slice, as `trajectory` (NaN: in no shared cell): where
    // the passes still disagree (a drift the INS did not report shows as one stretch).
    std::vector<double> final_slice_consistency_m;
    double initial_pair_score_m = 0;  // pair score of the input trajectory
    double final_pair_score_m = 0;    // ... and of the result (the kept iterate)
    SlamTimings timings;
    SlamMemory memory;
    SlamPosterior posterior;  // of the semi-rigid result (not computed after the rigid only)
    SlamTermination termination = SlamTermination::kInvalidInput;
    std::string message;
};

// Told after every iteration of either stage, with its record (stage, iteration, pairs,
// cost, ...); returning false cancels the run (SlamTermination::kCancelled).
using SlamProgress = std::function<bool(const SlamIteration&)>;

// Runs both stages. Never throws for bad data; degenerate input ends with a termination
// reason and the initial trajectory.
SlamResult RunSlam(const std::vector<Slice>& slices,
                   const SlamConfig& config,
                   const SlamProgress& progress = {});
// The same run, bit for bit, with the slices' points moved into SLAM's own array as they are
// read: the survey's points are held once, not twice (12 bytes a sounding). The slices are left
// with their times, poses and sigmas and no points.
SlamResult RunSlam(std::vector<Slice>&& slices,
                   const SlamConfig& config,
                   const SlamProgress& progress = {});

// A start for a perturbed SLAM run (SlamConfig::posterior_start_runs): the slices with their
// positions moved by one draw of the drift the INS reports. Per position component (east,
// north, up) the drift's 1-sigma is g = sqrt(sigma^2 - f^2), the reported sigma above the
// survey's smallest f (what the INS holds with GNSS), not allowed to fall faster than
// exp(-dt / recovery_time_s) (a filter regaining GNSS pulls its drift back over seconds, as
// SlamConfig::ins_sigma_recovery_time_s); where g exceeds 1 mm the slice moves by g times a
// unit-variance process: an integrated random walk of the velocity (dead reckoning's error)
// started where the stretch starts, divided by its own standard deviation. Attitudes, points
// and sigmas are unchanged; the draw depends on the seed and the slices' times alone.
std::vector<Slice> PerturbedStart(const std::vector<Slice>& slices,
                                  double recovery_time_s,
                                  std::uint64_t seed);

// The spread of SLAM's results from perturbed starts about `main` (a RunSlam trajectory):
// per pose of `main`, the 1-sigma east, north, up sqrt(mean_k d_k^2) of the position
// differences d_k of each run's pose of the same input slice (runs without that slice are
// skipped; zero where no run has it). How far SLAM's result depends on where it starts is how
// far it may be off where the data leave it a flat valley of its cost (docs/decisions/016).
std::vector<Eigen::Vector3d> StartSpread(const std::vector<SlamPose>& main,
                                         const std::vector<std::vector<SlamPose>>& runs);

// Applies a trajectory to the slices' points (world frame), for scoring and export.
std::vector<Eigen::Vector3f> PointsWorld(const std::vector<Slice>& slices,
                                         const std::vector<SlamPose>& trajectory);

}  // namespace pitmap::proc::slam
