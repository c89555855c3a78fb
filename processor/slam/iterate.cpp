// SPDX-License-Identifier: MIT
// One SLAM stage: ICP-like iterations (seed paper §4.2: "we solve for all poses at the same
// time and iterate like in the original ICP"), each a damped Gauss-Newton step on the sparse
// normal equations of eq. 2 (the rotation linearised on the manifold, slam_math.hpp), solved
// by the registration core's CHOLMOD solver.
#include <tbb/enumerable_thread_specific.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "processor/slam/internal.hpp"

namespace pitmap::proc::slam::detail {

namespace {

constexpr int kMaxDampingRetries = 8;
constexpr double kMinDamping = 1e-6;

// The pair search distance of iteration it: coarse to fine in the rigid stage's budget,
// d_i = d_0 (d_max / d_0)^((i - 1) / (n - 1)); max_pair_distance_m otherwise.
double SearchDistance(
    SlamStage stage, int it, int max_iterations, double rigid_d0_m, const SlamConfig& cfg) {
    if (stage == SlamStage::kRigid && max_iterations > 1 && it <= max_iterations) {
        const double f = static_cast<double>(it - 1) / static_cast<double>(max_iterations - 1);
        return rigid_d0_m * std::pow(cfg.max_pair_distance_m / rigid_d0_m, f);
    }
    return cfg.max_pair_distance_m;
}

// The best iterate by pair score so far, and the iterations since the last gain.
struct ScoreGuard {
    std::vector<Eigen::Matrix3d> best_R;
    std::vector<Eigen::Vector3d> best_t;
    int stalled = 0;
};

// Records `score`, the pair score of the previous step's result p, in that step's record, and
// p as the best iterate if it is. Returns true when the patience ran out (out says so): not
// while the rigid stage's pair distance is still shrinking (the truncated score sees little of
// the coarse alignment), nor when the stage is stopping anyway.
bool ScoreStalled(double score,
                  const Param& p,
                  double search_m,
                  bool stopping,
                  const SlamConfig& cfg,
                  double* best_score,
                  ScoreGuard& guard,
                  SlamResult& res,
                  StageOutcome& out) {
    SlamIteration& rec = res.iterations.back();
    rec.pair_score_m = score;
    // Only a gain beyond score_tolerance resets the patience.
    const bool gain = score < *best_score * (1.0 - cfg.score_tolerance);
    rec.best = score < *best_score;
    if (rec.best) {
        *best_score = score;
        guard.best_R = p.Rc;
        guard.best_t = p.tc;
    }
    if (gain) {
        guard.stalled = 0;
        return false;
    }
    if (++guard.stalled >= cfg.score_patience && !stopping &&
        search_m <= cfg.max_pair_distance_m * (1.0 + 1e-9)) {
        out.termination = SlamTermination::kScoreStalled;
        out.message = "pair score did not improve by more than " +
                      std::to_string(cfg.score_tolerance) + " (relative) for " +
                      std::to_string(cfg.score_patience) +
                      " iterations; last iterate kept unless worse than the best";
        return true;
    }
    return false;
}

// The normal equations of eq. 2 at T: the pose terms and the pairs' terms (accumulated per
// thread, then merged).
Terms BuildNormalEquations(const Input& in,
                           const Param& p,
                           const std::vector<Pose>& T,
                           const std::vector<Pair>& pairs,
                           const SlamConfig& cfg,
                           SlamResult& res) {
    const std::size_t n = p.num_nodes();
    auto t0 = Clock::now();
    Terms total(n);
    AddPoseTerms(in, p, T, cfg, /*linearise=*/true, total);
    tbb::enumerable_thread_specific<Terms> accs([n] { return Terms(n); });
    AddPairTerms(in, p, T, pairs, cfg, /*linearise=*/true, accs);
    res.timings.build_s += Seconds(t0);
    t0 = Clock::now();
    for (const Terms& acc : accs) {
        total.sys.Merge(acc.sys);
        total.cost += acc.cost;
        total.sq_dist += acc.sq_dist;
    }
    res.timings.build_s += Seconds(t0);
    return total;
}

// The outcome of a damped Gauss-Newton step from p.
struct DampedStep {
    bool accepted = false;              // a step lowered the cost on the pairs
    bool solved = false;                // some damping factorised
    Param trial;                        // the step's iterate
    double max_rot = 0, max_trans = 0;  // its largest node update, rad and m
};

// Solves with damping `lambda`, growing it tenfold until the step lowers the cost on the
// pairs (kMaxDampingRetries times at most); rec gets cost_after and the rejected steps.
DampedStep TryStep(WindowedSolver& ne,
                   const Input& in,
                   const Param& p,
                   const std::vector<Pair>& pairs,
                   const SlamConfig& cfg,
                   double& lambda,
                   SlamIteration& rec,
                   SlamResult& res) {
    const std::size_t n = p.num_nodes();
    DampedStep step;
    step.trial = p;
    for (int attempt = 0; attempt <= kMaxDampingRetries && !step.accepted; ++attempt) {
        auto t0 = Clock::now();
        Eigen::VectorXd delta;
        const bool ok = ne.Solve(lambda, &delta);
        res.timings.solve_s += Seconds(t0);
        if (!ok) {
            lambda *= 10.0;
            continue;
        }
        step.solved = true;
        step.max_rot = step.max_trans = 0;
        for (std::size_t k = 0; k < n; ++k) {
            const Vector6d d = delta.segment<6>(static_cast<Eigen::Index>(6 * k));
            step.trial.Rc[k] = ExpSO3(d.head<3>()) * p.Rc[k];
            step.trial.tc[k] = p.tc[k] + d.tail<3>();
            step.max_rot = std::max(step.max_rot, d.head<3>().norm());
            step.max_trans = std::max(step.max_trans, d.tail<3>().norm());
        }
        t0 = Clock::now();
        rec.cost_after = CostAt(in, step.trial, pairs, cfg);
        res.timings.build_s += Seconds(t0);
        step.accepted = rec.cost_after < rec.cost;
        if (!step.accepted) {
            lambda *= 10.0;
            ++rec.rejected_steps;
        }
    }
    return step;
}

}  // namespace

// Gauss-Newton with re-found correspondences (ICP-like). Guards, so that the result is never
// worse than the start:
//  - a step is taken only if it lowers the total cost on the pairs it was computed from;
//    otherwise the Levenberg damping grows (kMaxDampingRetries times at most, then the stage
//    ends with kNoImprovement);
//  - the pair score (truncated closest-point RMS at max_pair_distance_m over the overlap) of
//    every iterate is measured with the next search; the stage ends after score_patience
//    iterations without a gain beyond score_tolerance. The stage's last iterate is kept unless
//    its score is worse than the best iterate's by more than score_tolerance; then the best
//    one is. (The score is a guard, not the objective: its floor is the point spacing, so
//    iterates a few mm apart tie within the tolerance, and keeping the lowest of those threw
//    away later iterations that the step guard had accepted: gps-outage ATE 0.100 m keeping
//    the last, 0.122 m keeping the lowest.)
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
                      SlamResult& res) {
    StageOutcome out;
    ScoreGuard guard{p.Rc, p.tc, 0};
    double last_score = *best_score;  // the score of the current iterate p
    double lambda = kMinDamping;
    bool stop = false;
    std::vector<Eigen::Vector3f> pw(in.points.size());
    for (int it = 1;; ++it) {
        const double search_m = SearchDistance(stage, it, max_iterations, rigid_d0_m, cfg);
        const std::vector<Pose> T = SlicePoses(p);
        Search found = SearchPairs(in, T, stage, search_m, blocks, slice_block, pw, cfg, res);
        if (it == 1 && res.iterations.empty()) {
            *best_score = found.score;
            res.initial_pair_score_m = found.score;
        }
        last_score = found.score;
        if (it > 1 &&
            ScoreStalled(found.score, p, search_m, stop, cfg, best_score, guard, res, out)) {
            stop = true;
        }
        if (stop || it > max_iterations) break;
        const std::vector<Pair>& pairs = found.pairs;
        out.num_links = std::max(out.num_links, found.num_links);
        out.num_pairs = pairs.size();
        if (pairs.empty()) {
            out.termination = SlamTermination::kNoOverlap;
            out.message = "no point pairs at least " + std::to_string(cfg.min_time_separation_s) +
                          " s apart and closer than " + std::to_string(search_m) + " m";
            break;
        }

        const Terms total = BuildNormalEquations(in, p, T, pairs, cfg, res);
        auto t0 = Clock::now();
        // Both stages by windows in time (SlamConfig::semi_rigid_window_s, rigid_window_s),
        // their cores offset by half a core every other iteration, over a coarse level of
        // nodes interpolated in time (docs/decisions/017, 021).
        const bool rigid = stage == SlamStage::kRigid;
        const double window_s = rigid ? cfg.rigid_window_s : cfg.semi_rigid_window_s;
        const double overlap_s =
            rigid ? cfg.rigid_window_overlap_s : cfg.semi_rigid_window_overlap_s;
        WindowedSolver ne(total.sys,
                          MakeWindows(in, p, window_s, overlap_s, it % 2 == 0 ? 0.5 : 0.0),
                          MakeCoarseSpace(in, p, WindowCoarseSeconds(stage, cfg)));
        res.timings.build_s += Seconds(t0);
        SlamIteration rec;
        rec.windows = ne.num_windows();
        rec.stage = stage;
        rec.iteration = it;
        rec.num_pairs = pairs.size();
        rec.num_section_pairs = found.num_section_pairs;
        rec.max_section_partners = found.max_section_partners;
        rec.normal_equation_blocks = total.sys.num_off_diagonal();
        rec.cost = total.cost;
        rec.pair_rms_m = std::sqrt(total.sq_dist / static_cast<double>(pairs.size()));
        const DampedStep step = TryStep(ne, in, p, pairs, cfg, lambda, rec, res);
        rec.factor_nonzeros = ne.factor_nonzeros();
        rec.factor_flops = ne.factor_flops();
        rec.damping = lambda;
        out.iterations = it;
        if (!step.accepted) {
            rec.cost_after = rec.cost;
            rec.pair_score_m = found.score;  // no step taken: the iterate is unchanged
            res.iterations.push_back(rec);
            out.termination =
                step.solved ? SlamTermination::kNoImprovement : SlamTermination::kSolverFailed;
            out.message = step.solved
                              ? "no step lowered the cost on the current pairs (damping up to " +
                                    std::to_string(lambda / 10.0) +
                                    "); last accepted iterate kept unless worse than the best"
                              : "CHOLMOD could not factorise the normal equations";
            break;
        }

        lambda = std::max(kMinDamping, lambda / 10.0);
        p.Rc = step.trial.Rc;
        p.tc = step.trial.tc;
        rec.max_step_rotation_rad = step.max_rot;
        rec.max_step_translation_m = step.max_trans;
        t0 = Clock::now();
        rec.consistency_m = ConsistencyScore(in, SlicePoses(p), cfg);
        res.timings.score_s += Seconds(t0);
        res.iterations.push_back(rec);
        if (step.max_rot < cfg.convergence_rotation_rad &&
            step.max_trans < cfg.convergence_translation_m) {
            out.termination = SlamTermination::kConverged;
            out.message = "pose updates below the convergence thresholds";
            stop = true;  // score this iterate, then stop
        } else if (progress && !progress(res.iterations.back())) {
            out.termination = SlamTermination::kCancelled;
            out.message = "cancelled";
            stop = true;
        } else if (it == max_iterations) {
            out.message = "iteration budget spent";
        }
    }
    if (last_score > *best_score * (1.0 + cfg.score_tolerance)) {
        p.Rc = guard.best_R;
        p.tc = guard.best_t;
    } else {
        *best_score = last_score;  // the kept iterate's score: the next stage's reference
    }
    return out;
}

}  // namespace pitmap::proc::slam::detail
