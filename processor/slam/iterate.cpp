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
    constexpr int kMaxDampingRetries = 8;
    constexpr double kMinDamping = 1e-6;
    StageOutcome out;
    const std::size_t n = p.num_nodes();
    std::vector<Eigen::Matrix3d> best_R = p.Rc;
    std::vector<Eigen::Vector3d> best_t = p.tc;
    double last_score = *best_score;  // the score of the current iterate p
    int stalled = 0;
    double lambda = kMinDamping;
    bool stop = false;
    std::vector<Eigen::Vector3f> pw(in.points.size());
    for (int it = 1;; ++it) {
        double search_m = cfg.max_pair_distance_m;
        if (stage == SlamStage::kRigid && max_iterations > 1 && it <= max_iterations) {
            // d_i = d_0 (d_max / d_0)^((i - 1) / (n - 1)): coarse to fine.
            const double f = static_cast<double>(it - 1) / static_cast<double>(max_iterations - 1);
            search_m = rigid_d0_m * std::pow(cfg.max_pair_distance_m / rigid_d0_m, f);
        }
        const std::vector<Pose> T = SlicePoses(p);
        Search found = SearchPairs(in, T, stage, search_m, blocks, slice_block, pw, cfg, res);
        if (it == 1 && res.iterations.empty()) {
            *best_score = found.score;
            res.initial_pair_score_m = found.score;
        }
        last_score = found.score;
        if (it > 1) {
            // The score of the previous step's result.
            SlamIteration& rec = res.iterations.back();
            rec.pair_score_m = found.score;
            // Only a gain beyond score_tolerance resets the patience.
            const bool gain = found.score < *best_score * (1.0 - cfg.score_tolerance);
            rec.best = found.score < *best_score;
            if (rec.best) {
                *best_score = found.score;
                best_R = p.Rc;
                best_t = p.tc;
            }
            if (gain) {
                stalled = 0;
            } else if (++stalled >= cfg.score_patience && !stop &&
                       search_m <= cfg.max_pair_distance_m * (1.0 + 1e-9)) {
                // (Not while the rigid stage's pair distance is still shrinking: the truncated
                // score sees little of the coarse alignment.)
                out.termination = SlamTermination::kScoreStalled;
                out.message = "pair score did not improve by more than " +
                              std::to_string(cfg.score_tolerance) + " (relative) for " +
                              std::to_string(cfg.score_patience) +
                              " iterations; last iterate kept unless worse than the best";
                stop = true;
            }
        }
        if (stop || it > max_iterations) break;
        std::vector<Pair>& pairs = found.pairs;
        out.num_links = std::max(out.num_links, found.num_links);
        out.num_pairs = pairs.size();
        if (pairs.empty()) {
            out.termination = SlamTermination::kNoOverlap;
            out.message = "no point pairs at least " + std::to_string(cfg.min_time_separation_s) +
                          " s apart and closer than " + std::to_string(search_m) + " m";
            break;
        }
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
        reg::DampedSolver<6> ne(total.sys);
        res.timings.build_s += Seconds(t0);
        SlamIteration rec;
        rec.stage = stage;
        rec.iteration = it;
        rec.num_pairs = pairs.size();
        rec.cost = total.cost;
        rec.pair_rms_m = std::sqrt(total.sq_dist / static_cast<double>(pairs.size()));
        bool accepted = false, solved = false;
        Param trial = p;
        double max_rot = 0, max_trans = 0;
        for (int attempt = 0; attempt <= kMaxDampingRetries && !accepted; ++attempt) {
            t0 = Clock::now();
            Eigen::VectorXd delta;
            const bool ok = ne.Solve(lambda, &delta);
            res.timings.solve_s += Seconds(t0);
            if (!ok) {
                lambda *= 10.0;
                continue;
            }
            solved = true;
            max_rot = max_trans = 0;
            for (std::size_t k = 0; k < n; ++k) {
                const Vector6d d = delta.segment<6>(static_cast<Eigen::Index>(6 * k));
                trial.Rc[k] = ExpSO3(d.head<3>()) * p.Rc[k];
                trial.tc[k] = p.tc[k] + d.tail<3>();
                max_rot = std::max(max_rot, d.head<3>().norm());
                max_trans = std::max(max_trans, d.tail<3>().norm());
            }
            t0 = Clock::now();
            rec.cost_after = CostAt(in, trial, pairs, cfg);
            res.timings.build_s += Seconds(t0);
            accepted = rec.cost_after < rec.cost;
            if (!accepted) {
                lambda *= 10.0;
                ++rec.rejected_steps;
            }
        }
        rec.damping = lambda;
        out.iterations = it;
        if (!accepted) {
            rec.cost_after = rec.cost;
            rec.pair_score_m = found.score;  // no step taken: the iterate is unchanged
            res.iterations.push_back(rec);
            out.termination =
                solved ? SlamTermination::kNoImprovement : SlamTermination::kSolverFailed;
            out.message = solved ? "no step lowered the cost on the current pairs (damping up to " +
                                       std::to_string(lambda / 10.0) +
                                       "); last accepted iterate kept unless worse than the best"
                                 : "CHOLMOD could not factorise the normal equations";
            break;
        }
        lambda = std::max(kMinDamping, lambda / 10.0);
        p.Rc = trial.Rc;
        p.tc = trial.tc;
        rec.max_step_rotation_rad = max_rot;
        rec.max_step_translation_m = max_trans;
        t0 = Clock::now();
        rec.consistency_m = ConsistencyScore(in, SlicePoses(p), cfg);
        res.timings.score_s += Seconds(t0);
        res.iterations.push_back(rec);
        if (max_rot < cfg.convergence_rotation_rad && max_trans < cfg.convergence_translation_m) {
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
        p.Rc = best_R;
        p.tc = best_t;
    } else {
        *best_score = last_score;  // the kept iterate's score: the next stage's reference
    }
    return out;
}

}  // namespace pitmap::proc::slam::detail
