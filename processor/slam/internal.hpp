// SPDX-License-Identifier: MIT
// Internal to processor/slam: what the files of the SLAM stage share. The method follows the
// seed paper §4.2 (Elseberg, Borrmann & Nuechter 2013; Borrmann et al. 2008):
//   correspondences.cpp  sections (k-d tree blocks), closest-point pairs at least t_d apart,
//                        normals, the pair and consistency scores;
//   terms.cpp            the parametrisation (node corrections) and the residual terms of the
//                        normal equations: n-scan pairs (eq. 2), INS relative motion and priors;
//   coarse_search.cpp    the horizontal search that puts drifted sections into capture range;
//   iterate.cpp          one stage's ICP-like Gauss-Newton loop on the damped sparse solver;
//   rigid_stage.cpp      globally consistent matching of rigid sections (Borrmann et al. 2008);
//   semi_rigid_stage.cpp the semi-rigid stage, one pose per bin (Elseberg et al. 2013);
//   windows.cpp          the semi-rigid step's solve by windows in time over a coarse level;
//   posterior.cpp        the marginal covariances of the semi-rigid result;
//   start_spread.cpp     the spread of SLAM's result over runs from perturbed starts;
//   slam.cpp             input, configuration and the two stages in order.
// Neighbour search, normals, correspondence types, robust kernels, grid keys and the solver
// come from the registration core (processor/registration), shared with calibration.
#pragma once

#include <tbb/enumerable_thread_specific.h>

#include <algorithm>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "processor/registration/correspondence.hpp"
#include "processor/registration/neighbours.hpp"
#include "processor/registration/normal_equations.hpp"
#include "processor/slam/slam.hpp"
#include "processor/slam/slam_math.hpp"

namespace pitmap::proc::slam::detail {

using Clock = std::chrono::steady_clock;

inline double Seconds(Clock::time_point a) {
    return std::chrono::duration<double>(Clock::now() - a).count();
}

// ---- input, sorted by time ------------------------------------------------------------------

struct Input {
    std::vector<std::size_t> input_index;  // sorted slice -> input slice
    std::vector<double> t_s;
    std::vector<Pose> T_ins;      // INS poses (measurements)
    std::vector<Vector6d> sigma;  // effective INS 1-sigma (see ins_sigma_recovery_time_s)
    Vector6d sigma_floor = Vector6d::Zero();  // smallest sigma of the survey, per component
    // White noise of each INS position output, east, north, up (PositionWhiteNoise).
    Eigen::Vector3d position_white_sigma = Eigen::Vector3d::Zero();
    std::vector<std::size_t> offset;      // first point of each slice in `points`
    std::vector<Eigen::Vector3f> points;  // vehicle frame, finite only
    std::size_t points_in = 0;  // finite points given, before SlamConfig::pass_cell_m's bound
    std::size_t sections_every_point = 0;  // left whole by pass_cell_max_sigma_m
    // Slices where GNSS returns after an outage: the INS pulls its drift back within seconds
    // there, so sections and bins start there and are short after them (the correction stays
    // continuous; its rate changes).
    std::vector<std::size_t> breaks;
    std::size_t num_slices() const { return t_s.size(); }
    bool IsBreak(std::size_t s) const {
        return std::binary_search(breaks.begin(), breaks.end(), s);
    }
};

constexpr double kBreakFirstSectionS = 1.0;  // first section after a GNSS recovery

// ---- parametrisation: node corrections applied to per-slice base poses ----------------------
// Slice pose: R = Rc * R_base, t = Rc (t_base - pivot) + pivot + tc, with (Rc, tc) the node
// correction (interpolated between two nodes with weight alpha in a bin).

struct Param {
    std::vector<Pose> base;
    std::vector<Eigen::Vector3d> pivot;
    std::vector<int> k0, k1;
    std::vector<double> alpha;
    std::vector<int> anchor;  // node -> slice whose pose depends on that node alone
    std::vector<Eigen::Matrix3d> Rc;
    std::vector<Eigen::Vector3d> tc;
    std::size_t num_nodes() const { return anchor.size(); }
};

Param MakeParam(const std::vector<Pose>& base, const std::vector<std::size_t>& node_start);
void SliceCorrection(const Param& p, std::size_t s, Eigen::Matrix3d* R, Eigen::Vector3d* t);
std::vector<Pose> SlicePoses(const Param& p);
// d(slice pose perturbation) / d(node increment), times the interpolation weight w.
Matrix6d NodeToSlice(const Param& p, const Pose& T_s, std::size_t s, double w);

// ---- windows of both stages' solves (windows.cpp; SlamConfig::*_window_s) -------------------

// Nodes [first, last) of one window; its core [core_first, core_last) is what it contributes.
struct NodeWindow {
    std::size_t first = 0, last = 0;
    std::size_t core_first = 0, core_last = 0;
};

// The windows of p's nodes by their anchor slices' times: floor(duration / window_s) cores of
// equal duration (at least one), their boundaries moved by shift (in [0, 1), a share of a core:
// 0.5 gives the cores whose boundaries are the other set's centres, with half cores at the
// ends), each window holding the nodes within overlap_s of its core. One window holding every node
// when the survey is shorter than 2 window_s or window_s is 0. Cores partition the nodes, in order.
std::vector<NodeWindow> MakeWindows(
    const Input& in, const Param& p, double window_s, double overlap_s, double shift);

// The coarse level of the windowed solve: node k's correction is interpolated linearly in time
// between coarse nodes every coarse_s (hat functions): x_k = (1 - w_k) X_{a_k} + w_k X_{a_k + 1}.
struct CoarseSpace {
    std::size_t size = 0;          // coarse nodes
    std::vector<std::uint32_t> a;  // per node: its coarse node before it
    std::vector<double> w;         // ... and the weight of the one after it (0 at the last)
};
CoarseSpace MakeCoarseSpace(const Input& in, const Param& p, double coarse_s);

// The coarse level's node spacing of a stage's windows, s: the stage's *_window_coarse_s, or
// when 0 a tenth of its window length; never below section_length_s (the rigid stage's nodes
// are one per section; a finer coarse level would be the whole system again).
double WindowCoarseSeconds(SlamStage stage, const SlamConfig& cfg);

// The damped solve of a block system, whole or by windows. One window: reg::DampedSolver as it
// is. Several: one two-level multiplicative Schwarz sweep (Smith, Bjorstad & Gropp 1996,
// ch. 1-2; restricted: Cai & Sarkis 1999) on A = H + lambda diag(H): first the coarse problem
// (P^T A P) X = -P^T g with P the coarse space's interpolation, x = P X, which moves what no
// window sees whole (a drift over many windows, the survey's gauge); then the windows in order
// (block Gauss-Seidel over overlapping blocks), each solving A_WW x_W = -(g_W + A_WO x_O) with
// x_O the latest values outside it, keeping x on its core. Each solve minimises the damped
// quadratic model over its own unknowns given the rest, so the sweep lowers the model as a
// whole step does; it is not the whole solve's step (links to later windows lag by one sweep),
// and the stage's ICP iterations go on from it. Holds one window's factor at a time (and the
// coarse one). `sys` must outlive the solver.
class WindowedSolver {
public:
    WindowedSolver(const reg::BlockSystem<6>& sys,
                   std::vector<NodeWindow> windows,
                   CoarseSpace coarse = {});
    // As reg::DampedSolver::Solve; false when a window could not be factorised.
    bool Solve(double lambda, Eigen::VectorXd* delta);
    // The largest window's factor nonzeros, and the flops of one sweep (known after a Solve).
    double factor_nonzeros() const { return factor_nonzeros_; }
    double factor_flops() const { return factor_flops_; }
    std::size_t num_windows() const { return windows_.size(); }

private:
    const reg::BlockSystem<6>& sys_;
    std::vector<NodeWindow> windows_;
    CoarseSpace coarse_;
    std::unique_ptr<reg::DampedSolver<6>> whole_;  // one window
    // x = P X for the damped system (false when it could not be factorised).
    bool SolveCoarse(double lambda, Eigen::VectorXd* x);
    // Off-diagonal blocks by row node (both triangles): row_start_[i] .. row_start_[i + 1]
    // index link_node_ / link_block_; H_ij = link_block_ (transposed when link_transposed_).
    std::vector<std::size_t> row_start_;
    std::vector<std::uint32_t> link_node_;
    std::vector<const Matrix6d*> link_block_;
    std::vector<char> link_transposed_;
    double factor_nonzeros_ = 0, factor_flops_ = 0;
};

// A copy of p whose nodes are p's nodes [first, last), numbered from 0: its terms (AddPoseTerms,
// AddPairTerms of pairs whose slices' nodes all lie in the window) build the window's own
// normal equations. Slices outside the window keep node 0 and must not be used.
Param WindowParam(const Param& p, std::size_t first, std::size_t last);

// ---- sections and correspondences (correspondences.cpp) -------------------------------------

using SectionTree = reg::PointIndex<float, std::uint32_t>;

// A section of consecutive slices: the rigid stage's unit and a k-d tree block of world points.
struct Block {
    std::size_t s0 = 0, s1 = 0;                    // slices [s0, s1)
    std::size_t p0 = 0, p1 = 0;                    // points [p0, p1)
    double t0 = 0, t1 = 0;                         // time span
    Eigen::Vector3f lo = Eigen::Vector3f::Zero();  // bounding box of the world points
    Eigen::Vector3f hi = Eigen::Vector3f::Zero();
    // Over the block's world points; 32-bit indices (a block is seconds of pings): the trees
    // are held for the whole survey.
    std::unique_ptr<SectionTree> tree;
    // The normal-fit neighbours of block points, found once per run (see LocalNormals in
    // correspondences.cpp): (block-local point, slot) sorted by point, for the points that
    // needed a normal so far; per slot normal_neighbours block-local indices, each in as many
    // bits as the block's point count needs (the count itself past the last found), a slot in
    // whole words (NeighbourPacking): the tables live for the whole run, a fifth of the
    // survey's points have one, and 32 bits an index were a third of SLAM's arrays.
    std::vector<std::pair<std::uint32_t, std::uint32_t>> neighbour_slots;
    std::vector<std::uint64_t> neighbours;
    // The slot of block-local point `local`, kNoSlot when it has none.
    std::uint32_t NeighbourSlot(std::uint32_t local) const {
        const auto it = std::lower_bound(neighbour_slots.begin(),
                                         neighbour_slots.end(),
                                         std::make_pair(local, std::uint32_t{0}));
        return it != neighbour_slots.end() && it->first == local ? it->second : kNoSlot;
    }
    static constexpr std::uint32_t kNoSlot = 0xFFFFFFFFu;
};

// The sections' first slices in time order, and num_slices() after the last: sections of
// length_s, shorter after a GNSS recovery (in.t_s and in.breaks only; no points needed).
std::vector<std::size_t> SectionStarts(const Input& in, double length_s);
std::vector<Block> MakeBlocks(const Input& in, double length_s);

// ---- the points each pass contributes, bounded per cell (point_bound.cpp) -------------------

// Which of the slices' finite points enter SLAM (SlamConfig::pass_cell_m, decision 036): per
// section (sections given by their first slices, `section_start`, the last entry the slice
// count) and per cube of cell_m on a side in the world frame by the poses T (one per slice),
// the first per_cell finite points in time order (slice by slice, each slice's in its order).
// points[s] is slice s's points (vehicle frame, non-finite ones skipped and not counted); the
// result holds one flag (1 = kept) per finite point, slice by slice. cell_m 0: every point.
// Deterministic: a function of the arguments only (sections are independent: made in
// parallel).
// `every_point` (one flag per section, or empty): the sections flagged keep every point.
std::vector<std::uint8_t> BoundPointsPerCell(
    const std::vector<const std::vector<Eigen::Vector3f>*>& points,
    const std::vector<Pose>& T,
    const std::vector<std::size_t>& section_start,
    double cell_m,
    int per_cell,
    const std::vector<char>& every_point = {});
// Per section of `section_start` (SectionStarts): 1 where the INS's horizontal 1-sigma (the
// larger of in.sigma's east and north) exceeds max_sigma_m at any of its slices (a GNSS
// outage: SlamConfig::pass_cell_max_sigma_m); all 0 when max_sigma_m is 0.
std::vector<char> SectionsKeepingEveryPoint(const Input& in,
                                            const std::vector<std::size_t>& section_start,
                                            double max_sigma_m);

// How a block's neighbour slots are packed: `bits` per block-local index (enough for `none`,
// the block's point count, which ends a slot's list), `k` indices a slot in `words` 64-bit words
// (whole words: slots are written in parallel).
struct NeighbourPacking {
    std::uint32_t none = 0;
    int bits = 1;
    std::size_t k = 0;
    std::size_t words = 0;
    NeighbourPacking(const Block& b, std::size_t k);
    // Slot words <- idx[0, n) and `none` after them (n <= k); the words must be zero.
    void Pack(const std::size_t* idx, std::size_t n, std::uint64_t* words_out) const;
    // out[0, k) <- the slot's indices.
    void Unpack(const std::uint64_t* words_in, std::uint32_t* out) const;
};

// The partner blocks of a query point recorded at time t in block `own`, among the blocks
// `listed` in its cell (ascending indices, as ListBlocksByCell makes them): the blocks recorded
// entirely at least td before t and those at least td after it, ascending. A pass is a run of
// consecutive block indices among them (one visit of the vehicle over the cell); on each side
// only the max_passes passes nearest in time to t are kept (0: all of them). The seed paper
// pairs a point with every point at least t_d away; over a cell that N passes see, that is
// O(N) trees per query and O(N^2) section links (and fill of the normal equations) per cell,
// so a survey's cost grows with the square of its duration. The nearest passes in time are the
// ones the INS drifted least against, and keep the section graph banded in time.
// Deterministic: a function of the lists and the times only.
void PartnerBlocks(const std::vector<Block>& blocks,
                   const std::vector<std::uint32_t>& listed,
                   std::uint32_t own,
                   double t,
                   double td,
                   int max_passes,
                   std::vector<std::uint32_t>& partners);

// A correspondence (global point indices) with the slices and blocks of both sides.
struct Pair {
    reg::Correspondence c;
    std::uint32_t slice_a = 0, slice_b = 0;
    std::uint32_t block_a = 0, block_b = 0;
};

// Pairs of the current iterate and the pair score.
struct Search {
    std::vector<Pair> pairs;
    double score = 0;
    std::size_t num_links = 0;             // rigid: section links with enough pairs
    std::size_t num_section_pairs = 0;     // distinct section pairs of `pairs`
    std::size_t max_section_partners = 0;  // most sections one section shares pairs with
};

// Moves the points to the world with T, rebuilds the k-d trees and finds the pairs within
// search_m (with normals when the correspondence type needs them); the rigid stage keeps only
// links between sections with enough pairs (the paper's overlap heuristic).
Search SearchPairs(const Input& in,
                   const std::vector<Pose>& T,
                   SlamStage stage,
                   double search_m,
                   std::vector<Block>& blocks,
                   const std::vector<std::uint32_t>& slice_block,
                   std::vector<Eigen::Vector3f>& pw,
                   const SlamConfig& cfg,
                   SlamResult& res);

// Plane-fit vertical RMS over grid cells that hold query points of passes at least t_d apart.
double ConsistencyScore(const Input& in, const std::vector<Pose>& T, const SlamConfig& cfg);
// The same score, and the same cells' plane residuals as an RMS per slice (NaN where a slice
// has no point in a cell that several passes share): where along the survey the passes
// disagree. One pass over the cells for both.
struct Consistency {
    double score_m = 0;
    std::vector<double> by_slice_m;
};
Consistency ConsistencyBySlice(const Input& in, const std::vector<Pose>& T, const SlamConfig& cfg);

// ---- residual terms (terms.cpp) --------------------------------------------------------------

// Normal equations of one linearisation (or, with linearise false, the cost only).
struct Terms {
    reg::BlockSystem<6> sys;
    double cost = 0;
    double sq_dist = 0;  // sum of squared pair distances
    explicit Terms(std::size_t num_nodes) : sys(num_nodes) {}
};

// Relative-motion, drift-smoothness and absolute terms (no pairs).
void AddPoseTerms(const Input& in,
                  const Param& p,
                  const std::vector<Pose>& T,
                  const SlamConfig& cfg,
                  bool linearise,
                  Terms& acc);
// What a pair informs about: as its correspondence type says (GICP: along the surface too,
// with gicp_tangent_sigma_m), or along its normal alone (one row: the residual along the mean
// of both normals, with both points' sigma; the posterior's default, SlamPosterior).
enum class PairInformation { kAsConfigured, kNormalOnly };

// Pair terms; with linearise false only the robust cost (and sq_dist) are accumulated.
// weight_scale multiplies the terms' information (not the cost): the posterior's share of
// independent information of a cluster of correlated pairs.
void AddPairTerms(const Input& in,
                  const Param& p,
                  const std::vector<Pose>& T,
                  const std::vector<Pair>& pairs,
                  const SlamConfig& cfg,
                  bool linearise,
                  tbb::enumerable_thread_specific<Terms>& accs,
                  PairInformation info = PairInformation::kAsConfigured,
                  double weight_scale = 1.0);
// Total cost (INS terms and robust pair terms) of the parametrisation p on fixed pairs.
double CostAt(const Input& in,
              const Param& p,
              const std::vector<Pair>& pairs,
              const SlamConfig& cfg);

// ---- coarse horizontal search (coarse_search.cpp) -------------------------------------------

std::vector<Eigen::Vector3d> CoarseSectionSearch(const Input& in,
                                                 const std::vector<Pose>& T,
                                                 const std::vector<Block>& blocks,
                                                 const SlamConfig& cfg,
                                                 std::vector<SlamSection>* sections);

// ---- stages (iterate.cpp, rigid_stage.cpp, semi_rigid_stage.cpp) ----------------------------

struct StageOutcome {
    SlamTermination termination = SlamTermination::kMaxIterations;
    std::string message;
    int iterations = 0;
    std::size_t num_pairs = 0;
    std::size_t num_links = 0;
};

// One stage's iterations on the parametrisation p (see iterate.cpp).
StageOutcome RunStage(const Input& in,
                      Param& p,
                      SlamStage stage,
                      int max_iterations,
                      double rigid_d0_m,
                      std::vector<Block>& blocks,
                      const std::vector<std::uint32_t>& slice_block,
                      const SlamConfig& cfg,
                      const SlamProgress& progress,
                      double* best_score,
                      SlamResult& res);

// The rigid stage's parametrisation of the poses `current` (its base): one node per section of
// `blocks`, at the section's centre with the corrections interpolated in time between centres
// (SlamConfig::rigid_interpolate_sections), or rigid about the section's mean position.
Param RigidParam(const Input& in,
                 const std::vector<Pose>& current,
                 const std::vector<Block>& blocks,
                 const SlamConfig& cfg);

// The rigid stage from the poses `current`, which it replaces with its result.
StageOutcome RunRigidStage(const Input& in,
                           std::vector<Block>& blocks,
                           const std::vector<std::uint32_t>& slice_block,
                           const SlamConfig& cfg,
                           const SlamProgress& progress,
                           std::vector<Pose>& current,
                           double* best_score,
                           SlamResult& res);

// The semi-rigid stage from the poses `current`, which it replaces with its result.
StageOutcome RunSemiRigidStage(const Input& in,
                               std::vector<Block>& blocks,
                               const std::vector<std::uint32_t>& slice_block,
                               const SlamConfig& cfg,
                               const SlamProgress& progress,
                               std::vector<Pose>& current,
                               double* best_score,
                               SlamResult& res);

// The posterior of the parametrisation p (the semi-rigid stage's result) into res.posterior,
// one sigma per slice (posterior.cpp; SlamPosterior says what it is).
void ComputePosterior(const Input& in,
                      const Param& p,
                      std::vector<Block>& blocks,
                      const std::vector<std::uint32_t>& slice_block,
                      const SlamConfig& cfg,
                      SlamResult& res);

// posterior_start_runs SLAM runs from PerturbedStart draws of `slices` (without the posterior
// and without further runs), their StartSpread about res.trajectory added to
// res.posterior.slice_sigma's positions in quadrature (start_spread.cpp). False when cancelled
// through `progress` (the posterior is then left without the spread).
bool AddStartSpread(const std::vector<Slice>& slices,
                    const SlamConfig& cfg,
                    const SlamProgress& progress,
                    SlamResult& res);

}  // namespace pitmap::proc::slam::detail
