// SPDX-License-Identifier: MIT
// The semi-rigid SLAM stage (seed paper §4.2, after Elseberg et al. 2013): no rigidity
// assumption beyond the computation of correspondences; one pose correction per bin of slices,
// slice poses interpolated between bins, all solved together from the rigid stage's result
// (each step by overlapping windows in time over a coarse level on long surveys: windows.cpp).
#include <algorithm>

#include "processor/slam/internal.hpp"

namespace pitmap::proc::slam::detail {

StageOutcome RunSemiRigidStage(const Input& in,
                               std::vector<Block>& blocks,
                               const std::vector<std::uint32_t>& slice_block,
                               const SlamConfig& cfg,
                               const SlamProgress& progress,
                               std::vector<Pose>& current,
                               double* best_score,
                               SlamResult& res) {
    // Bins of bin_slices, restarted at every GNSS recovery with bins of 1, 1, 2, 4, ...
    // slices (the INS error falls fast there); slice poses are interpolated between bin
    // starts.
    std::vector<std::size_t> starts;
    const auto bin = static_cast<std::size_t>(cfg.bin_slices);
    std::size_t since_break = in.num_slices();  // slices since the last recovery
    for (std::size_t s = 0; s < in.num_slices();) {
        if (in.IsBreak(s)) since_break = 0;
        starts.push_back(s);
        const std::size_t len = std::clamp<std::size_t>(since_break, 1, bin);
        std::size_t next = s + 1;
        while (next < in.num_slices() && next < s + len && !in.IsBreak(next)) ++next;
        since_break += next - s;
        s = next;
    }
    Param p = MakeParam(current, starts);
    std::size_t k = 0;
    for (std::size_t s = 0; s < in.num_slices(); ++s) {
        while (k + 1 < starts.size() && starts[k + 1] <= s) ++k;
        p.pivot[s] = current[s].translation();
        p.k0[s] = p.k1[s] = static_cast<int>(k);
        p.alpha[s] = 0.0;
        if (k + 1 < starts.size() && s > starts[k]) {
            p.k1[s] = static_cast<int>(k + 1);
            p.alpha[s] =
                static_cast<double>(s - starts[k]) / static_cast<double>(starts[k + 1] - starts[k]);
        }
    }
    res.num_poses = starts.size();
    StageOutcome semi = RunStage(in,
                                 p,
                                 SlamStage::kSemiRigid,
                                 cfg.max_iterations,
                                 cfg.max_pair_distance_m,
                                 blocks,
                                 slice_block,
                                 cfg,
                                 progress,
                                 best_score,
                                 res);
    res.semi_rigid_iterations = semi.iterations;
    if (cfg.posterior && semi.termination != SlamTermination::kCancelled &&
        semi.termination != SlamTermination::kNoOverlap &&
        semi.termination != SlamTermination::kSolverFailed) {
        ComputePosterior(in, p, blocks, slice_block, cfg, res);
    }
    current = SlicePoses(p);
    if (semi.message.empty()) semi.message = "iteration budget spent";
    return semi;
}

}  // namespace pitmap::proc::slam::detail
