// SPDX-License-Identifier: MIT
// Continuous-time (semi-rigid) SLAM on sonar slices (seed paper §4.2): input checks and order,
// then the rigid stage and the semi-rigid stage. The pieces are in the files internal.hpp lists.
#include "processor/slam/slam.hpp"

#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <optional>
#include <utility>

#include "processor/slam/internal.hpp"

namespace pitmap::proc::slam {

using namespace detail;  // NOLINT(google-build-using-namespace): this folder's own internals

namespace {

// GNSS recoveries: the reported horizontal 1-sigma falls below half its largest value of the
// previous kBreakWindowS, from above min_sigma_m (one break per kBreakWindowS at most).
constexpr double kBreakWindowS = 2.0;
std::vector<std::size_t> FindBreaks(const std::vector<double>& t_s,
                                    const std::vector<Vector6d>& reported,
                                    double min_sigma_m) {
    std::vector<std::size_t> breaks;
    std::size_t w0 = 0;
    for (std::size_t s = 1; s < t_s.size(); ++s) {
        while (t_s[w0] < t_s[s] - kBreakWindowS) ++w0;
        double peak = 0;
        for (std::size_t k = w0; k < s; ++k) {
            peak = std::max(peak, std::max(reported[k](3), reported[k](4)));
        }
        const double now = std::max(reported[s](3), reported[s](4));
        const bool recent = !breaks.empty() && t_s[breaks.back()] > t_s[s] - kBreakWindowS;
        if (peak > min_sigma_m && now < 0.5 * peak && !recent) breaks.push_back(s);
    }
    return breaks;
}

bool FinitePose(const Pose& T) {
    return T.matrix().allFinite();
}

}  // namespace

const char* ToString(SlamTermination t) {
    switch (t) {
        case SlamTermination::kConverged:
            return "converged";
        case SlamTermination::kMaxIterations:
            return "max_iterations";
        case SlamTermination::kScoreStalled:
            return "score_stalled";
        case SlamTermination::kNoImprovement:
            return "no_improvement";
        case SlamTermination::kNoOverlap:
            return "no_overlap";
        case SlamTermination::kSolverFailed:
            return "solver_failed";
        case SlamTermination::kCancelled:
            return "cancelled";
        case SlamTermination::kInvalidInput:
            return "invalid_input";
    }
    return "unknown";
}

std::vector<std::string> SlamConfig::Validate() const {
    std::vector<std::string> p;
    if (!(min_time_separation_s >= 0)) p.push_back("min_time_separation_s must be >= 0");
    if (!(max_pair_distance_m > 0)) p.push_back("max_pair_distance_m must be > 0");
    if (!(rigid_max_pair_distance_m >= max_pair_distance_m)) {
        p.push_back("rigid_max_pair_distance_m must be >= max_pair_distance_m");
    }
    if (!(section_length_s > 0)) p.push_back("section_length_s must be > 0");
    if (!(reference_horizontal_sigma_m >= 0) || !std::isfinite(reference_horizontal_sigma_m)) {
        p.push_back("reference_horizontal_sigma_m must be finite and >= 0");
    }
    if (max_partner_passes < 0) p.push_back("max_partner_passes must be >= 0 (0 = all)");
    if (rigid_iterations < 0) p.push_back("rigid_iterations must be >= 0");
    if (min_section_link_pairs < 1) p.push_back("min_section_link_pairs must be >= 1");
    if (bin_slices < 1) p.push_back("bin_slices must be >= 1");
    if (max_iterations < 0) p.push_back("max_iterations must be >= 0");
    if (!(semi_rigid_window_s >= 0))
        p.push_back("semi_rigid_window_s must be >= 0 (0 = one system)");
    if (!(semi_rigid_window_overlap_s >= 0))
        p.push_back("semi_rigid_window_overlap_s must be >= 0");
    if (semi_rigid_window_s > 0 && !(semi_rigid_window_overlap_s > 0)) {
        p.push_back("semi_rigid_window_overlap_s must be > 0 when semi_rigid_window_s is set");
    }
    if (!(semi_rigid_window_coarse_s >= 0)) {
        p.push_back("semi_rigid_window_coarse_s must be >= 0 (0 = a tenth of the window)");
    }
    if (!(rigid_window_s >= 0)) p.push_back("rigid_window_s must be >= 0 (0 = one system)");
    if (rigid_window_s > 0 && !(rigid_window_overlap_s > 0)) {
        p.push_back("rigid_window_overlap_s must be > 0 when rigid_window_s is set");
    }
    if (!(rigid_window_coarse_s >= 0)) {
        p.push_back("rigid_window_coarse_s must be >= 0 (0 = a tenth of the window)");
    }
    if (posterior_batch_nodes < 1) p.push_back("posterior_batch_nodes must be >= 1");
    if (posterior_start_runs < 0) p.push_back("posterior_start_runs must be >= 0");
    if (!(convergence_rotation_rad >= 0)) p.push_back("convergence_rotation_rad must be >= 0");
    if (!(convergence_translation_m >= 0)) p.push_back("convergence_translation_m must be >= 0");
    if (normal_neighbours < 3 || normal_neighbours > kMaxNormalNeighbours)
        p.push_back("normal_neighbours must be in [3, " + std::to_string(kMaxNormalNeighbours) +
                    "]");
    if (!(point_sigma_m > 0)) p.push_back("point_sigma_m must be > 0");
    if (!(gicp_tangent_sigma_m > 0)) p.push_back("gicp_tangent_sigma_m must be > 0");
    if (!(robust_width > 0)) p.push_back("robust_width must be > 0");
    if (query_stride < 1) p.push_back("query_stride must be >= 1");
    if (!(pass_cell_m >= 0) || !std::isfinite(pass_cell_m)) {
        p.push_back("pass_cell_m must be finite and >= 0 (0 = every point)");
    }
    if (pass_cell_points < 1) p.push_back("pass_cell_points must be >= 1");
    if (!(pass_cell_max_sigma_m >= 0) || !std::isfinite(pass_cell_max_sigma_m)) {
        p.push_back("pass_cell_max_sigma_m must be finite and >= 0 (0 = every section bounded)");
    }
    if (!(ins_correlation_time_s > 0)) p.push_back("ins_correlation_time_s must be > 0");
    if (!(ins_sigma_scale > 0)) p.push_back("ins_sigma_scale must be > 0");
    if (!(min_relative_rotation_sigma_rad > 0)) {
        p.push_back("min_relative_rotation_sigma_rad must be > 0");
    }
    if (!(min_relative_translation_sigma_m > 0)) {
        p.push_back("min_relative_translation_sigma_m must be > 0");
    }
    if (!(ins_sigma_recovery_time_s >= 0)) p.push_back("ins_sigma_recovery_time_s must be >= 0");
    if (!(drift_velocity_random_walk_mps_per_sqrt_s >= 0)) {
        p.push_back("drift_velocity_random_walk_mps_per_sqrt_s must be >= 0");
    }
    if (!(absolute_sigma_scale > 0)) p.push_back("absolute_sigma_scale must be > 0");
    if (!(coarse_search_m >= 0)) p.push_back("coarse_search_m must be >= 0");
    if (!(coarse_search_step_m > 0)) p.push_back("coarse_search_step_m must be > 0");
    if (!(coarse_search_cell_m > 0)) p.push_back("coarse_search_cell_m must be > 0");
    if (!(coarse_search_min_sigma_m > 0)) p.push_back("coarse_search_min_sigma_m must be > 0");
    if (!(score_cell_m > 0)) p.push_back("score_cell_m must be > 0");
    if (score_patience < 1) p.push_back("score_patience must be >= 1");
    if (!(score_tolerance >= 0 && score_tolerance < 1)) {
        p.push_back("score_tolerance must be in [0, 1)");
    }
    if (num_threads < 0) p.push_back("num_threads must be >= 0 (0 = auto)");
    return p;
}

std::vector<Eigen::Vector3f> PointsWorld(const std::vector<Slice>& slices,
                                         const std::vector<SlamPose>& trajectory) {
    std::vector<Eigen::Vector3f> out;
    for (const SlamPose& sp : trajectory) {
        if (sp.input_index >= slices.size()) continue;
        const Eigen::Isometry3f T = sp.T_world_vehicle.cast<float>();
        for (const auto& x : slices[sp.input_index].points_vehicle) {
            if (x.allFinite()) out.push_back(T * x);
        }
    }
    return out;
}

namespace {

// Each slice's points back from `in` (its finite ones: all that SLAM reads of them).
void RestorePoints(const Input& in, std::vector<Slice>& slices) {
    for (std::size_t s = 0; s < in.num_slices(); ++s) {
        std::vector<Eigen::Vector3f>& out = slices[in.input_index[s]].points_vehicle;
        out.assign(in.points.begin() + static_cast<std::ptrdiff_t>(in.offset[s]),
                   in.points.begin() + static_cast<std::ptrdiff_t>(in.offset[s + 1]));
    }
}

void ReleasePoints(std::vector<Slice>& slices) {
    for (Slice& s : slices) std::vector<Eigen::Vector3f>().swap(s.points_vehicle);
}

// The slices' times, INS poses and sigmas in time order (ties by input index, so that the
// result does not depend on input order), the GNSS recoveries and the sigma floor.
Input ReadPoses(const std::vector<Slice>& slices, const SlamConfig& cfg) {
    Input in;
    std::vector<std::size_t> order(slices.size());
    std::iota(order.begin(), order.end(), std::size_t{0});
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
        return slices[a].gps_time_s < slices[b].gps_time_s;
    });
    in.input_index = order;
    for (std::size_t i : order) {
        const Slice& s = slices[i];
        in.t_s.push_back(s.gps_time_s);
        Pose T = s.T_world_vehicle;
        T.linear() = Eigen::Quaterniond(T.linear()).normalized().toRotationMatrix();
        in.T_ins.push_back(T);
        in.sigma.push_back(s.pose_sigma);
    }
    const std::size_t ns = in.num_slices();
    in.breaks = FindBreaks(in.t_s, in.sigma, cfg.coarse_search_min_sigma_m);
    in.sigma_floor = in.sigma.front();
    for (const Vector6d& sg : in.sigma) in.sigma_floor = in.sigma_floor.cwiseMin(sg);
    in.position_white_sigma = PositionWhiteNoise(in.t_s, in.T_ins);
    if (cfg.ins_sigma_recovery_time_s > 0) {
        for (std::size_t s = 1; s < ns; ++s) {
            const double decay =
                std::exp(-(in.t_s[s] - in.t_s[s - 1]) / cfg.ins_sigma_recovery_time_s);
            in.sigma[s] = in.sigma[s].cwiseMax(decay * in.sigma[s - 1]);
        }
    }
    return in;
}

// The Input of a run: ReadPoses, then the points that enter (BoundPointsPerCell by the INS
// poses and the sections), moved out of `owned` slice by slice when it is given.
Input ReadInput(const std::vector<Slice>& slices,
                std::vector<Slice>* owned,
                const SlamConfig& cfg) {
    Input in = ReadPoses(slices, cfg);
    std::vector<const std::vector<Eigen::Vector3f>*> sorted;
    sorted.reserve(slices.size());
    for (std::size_t i : in.input_index) sorted.push_back(&slices[i].points_vehicle);
    const std::vector<std::size_t> sections = SectionStarts(in, cfg.section_length_s);
    const std::vector<char> whole =
        cfg.pass_cell_m > 0 ? SectionsKeepingEveryPoint(in, sections, cfg.pass_cell_max_sigma_m)
                            : std::vector<char>{};
    in.sections_every_point = static_cast<std::size_t>(std::count(whole.begin(), whole.end(), 1));
    const std::vector<std::uint8_t> keep = BoundPointsPerCell(
        sorted, in.T_ins, sections, cfg.pass_cell_m, cfg.pass_cell_points, whole);
    in.points_in = keep.size();
    // Sized once: grown by push_back its capacity would be up to twice the points (and three
    // times while it moves), at 12 bytes a sounding the largest of SLAM's arrays.
    in.points.reserve(static_cast<std::size_t>(std::count(keep.begin(), keep.end(), 1)));
    in.offset.reserve(slices.size() + 1);
    in.offset.push_back(0);
    std::size_t k = 0;
    for (std::size_t s = 0; s < sorted.size(); ++s) {
        for (const auto& x : *sorted[s]) {
            if (!x.allFinite()) continue;
            if (keep[k++] != 0) in.points.push_back(x);
        }
        in.offset.push_back(in.points.size());
        if (owned != nullptr) {
            std::vector<Eigen::Vector3f>().swap((*owned)[in.input_index[s]].points_vehicle);
        }
    }
    return in;
}

// RunSlam on `slices`; `owned` is null or the same slices, whose points are then moved into
// SLAM's own array as they are read (the survey's points held once, not twice).
SlamResult Run(const std::vector<Slice>& slices,
               std::vector<Slice>* owned,
               const SlamConfig& cfg,
               const SlamProgress& progress) {
    const auto t_start = Clock::now();
    SlamResult res;
    const auto problems = cfg.Validate();
    if (!problems.empty()) {
        res.termination = SlamTermination::kInvalidInput;
        res.message = "invalid config: " + problems.front();
        for (std::size_t i = 1; i < problems.size(); ++i) res.message += "; " + problems[i];
        return res;
    }
    if (slices.empty()) {
        res.termination = SlamTermination::kInvalidInput;
        res.message = "no slices";
        return res;
    }
    for (std::size_t i = 0; i < slices.size(); ++i) {
        if (!std::isfinite(slices[i].gps_time_s) || !FinitePose(slices[i].T_world_vehicle) ||
            !slices[i].pose_sigma.allFinite() || (slices[i].pose_sigma.array() <= 0).any()) {
            res.termination = SlamTermination::kInvalidInput;
            res.message = "slice " + std::to_string(i) +
                          ": non-finite time or pose, or a pose sigma that is not > 0";
            return res;
        }
    }
    std::optional<tbb::global_control> threads;
    if (cfg.num_threads > 0) {
        threads.emplace(tbb::global_control::max_allowed_parallelism,
                        static_cast<std::size_t>(cfg.num_threads));
    }

    Input in = ReadInput(slices, owned, cfg);
    const std::size_t ns = in.num_slices();
    res.num_points_in = in.points_in;
    res.num_points = in.points.size();
    res.num_sections_every_point = in.sections_every_point;

    std::vector<Block> blocks = MakeBlocks(in, cfg.section_length_s);
    std::vector<std::uint32_t> slice_block(ns);
    for (std::uint32_t b = 0; b < blocks.size(); ++b) {
        for (std::size_t s = blocks[b].s0; s < blocks[b].s1; ++s) slice_block[s] = b;
    }
    res.num_sections = blocks.size();
    res.sections.resize(blocks.size());
    for (std::size_t b = 0; b < blocks.size(); ++b) {
        res.sections[b].t0_s = blocks[b].t0;
        res.sections[b].t1_s = blocks[b].t1;
    }

    auto t0 = Clock::now();
    res.initial_consistency_m = ConsistencyScore(in, in.T_ins, cfg);
    res.timings.score_s += Seconds(t0);
    double best_score = 0;  // pair score, set by the first search
    std::vector<Pose> current = in.T_ins;

    // Stage 1: rigid sections (rigid_stage.cpp); stage 2: semi-rigid (semi_rigid_stage.cpp).
    const StageOutcome rigid =
        RunRigidStage(in, blocks, slice_block, cfg, progress, current, &best_score, res);
    StageOutcome semi;
    semi.termination = rigid.termination;
    semi.message = rigid.message;
    if (cfg.max_iterations > 0 && rigid.termination != SlamTermination::kNoOverlap &&
        rigid.termination != SlamTermination::kCancelled) {
        semi = RunSemiRigidStage(in, blocks, slice_block, cfg, progress, current, &best_score, res);
    }
    res.num_pairs = semi.num_pairs != 0 ? semi.num_pairs : rigid.num_pairs;
    res.termination = semi.termination;
    res.message = semi.message;
    if (rigid.termination == SlamTermination::kNoOverlap) {
        res.message = "rigid stage: " + rigid.message + "; trajectory unchanged";
    }
    res.final_pair_score_m = res.iterations.empty() ? res.initial_pair_score_m : best_score;
    t0 = Clock::now();
    Consistency final_consistency = ConsistencyBySlice(in, current, cfg);
    res.final_consistency_m = final_consistency.score_m;
    res.final_slice_consistency_m = std::move(final_consistency.by_slice_m);
    res.timings.score_s += Seconds(t0);
    res.trajectory.resize(ns);
    for (std::size_t s = 0; s < ns; ++s) {
        res.trajectory[s].gps_time_s = in.t_s[s];
        res.trajectory[s].T_world_vehicle = current[s];
        res.trajectory[s].input_index = in.input_index[s];
    }
    res.timings.total_s = Seconds(t_start);
    if (!(cfg.posterior && cfg.posterior_start_runs > 0 && res.posterior.computed)) return res;
    // The perturbed-start runs each hold their own copy of the points, trees and tables: this
    // run's are released first (nothing below reads them but the points of owned slices).
    // They start from the points this run kept (not bounded again: the perturbed poses would
    // put other points in the cubes, and the spread would be the points' as well as the start's).
    std::vector<Block>().swap(blocks);
    std::vector<Slice> kept_copy;
    std::vector<Slice>* kept = owned;
    if (kept == nullptr && cfg.pass_cell_m > 0) {
        kept_copy.reserve(slices.size());
        for (const Slice& s : slices)
            kept_copy.push_back(Slice{s.gps_time_s, s.T_world_vehicle, {}, s.pose_sigma});
        kept = &kept_copy;
    }
    if (kept != nullptr) RestorePoints(in, *kept);
    in = Input{};
    SlamConfig start_cfg = cfg;
    start_cfg.pass_cell_m = 0;
    if (!AddStartSpread(kept != nullptr ? *kept : slices, start_cfg, progress, res)) {
        res.termination = SlamTermination::kCancelled;
        res.message = "cancelled during the perturbed-start runs of the posterior";
    }
    if (owned != nullptr) ReleasePoints(*owned);
    return res;
}

}  // namespace

SlamResult RunSlam(const std::vector<Slice>& slices,
                   const SlamConfig& cfg,
                   const SlamProgress& progress) {
    return Run(slices, nullptr, cfg, progress);
}

SlamResult RunSlam(std::vector<Slice>&& slices,
                   const SlamConfig& cfg,
                   const SlamProgress& progress) {
    return Run(slices, &slices, cfg, progress);
}

}  // namespace pitmap::proc::slam
