// SPDX-License-Identifier: MIT
// The rigid SLAM stage: globally consistent scan matching of sections (seed paper §4.2, after
// Borrmann et al. 2008: "we first split the trajectory into sections, and match these sections";
// the graph from the number of closest-point pairs between sections). Before it, drifted
// sections are moved into capture range by the coarse search (coarse_search.cpp).
#include <algorithm>
#include <cmath>

#include "processor/slam/internal.hpp"

namespace pitmap::proc::slam::detail {

Param RigidParam(const Input& in,
                 const std::vector<Pose>& current,
                 const std::vector<Block>& blocks,
                 const SlamConfig& cfg) {
    // Rigid sections, rotating about the section's mean position; or, with
    // rigid_interpolate_sections, one correction per section centre, interpolated in time
    // between centres (the corrected track stays continuous).
    std::vector<std::size_t> nodes;
    // Interpolated: a node at each section centre, but at the start of a section that
    // starts at a GNSS recovery (the INS error is continuous there, its rate is not).
    for (const Block& b : blocks) {
        nodes.push_back(cfg.rigid_interpolate_sections && !in.IsBreak(b.s0) ? (b.s0 + b.s1 - 1) / 2
                                                                            : b.s0);
    }
    Param p = MakeParam(current, nodes);
    for (std::size_t b = 0; b < blocks.size(); ++b) {
        Eigen::Vector3d c = Eigen::Vector3d::Zero();
        for (std::size_t s = blocks[b].s0; s < blocks[b].s1; ++s) c += current[s].translation();
        c /= static_cast<double>(blocks[b].s1 - blocks[b].s0);
        for (std::size_t s = blocks[b].s0; s < blocks[b].s1; ++s) {
            p.pivot[s] = c;
            p.k0[s] = p.k1[s] = static_cast<int>(b);
        }
    }
    if (cfg.rigid_interpolate_sections) {
        std::size_t k = 0;
        for (std::size_t s = 0; s < in.num_slices(); ++s) {
            while (k + 1 < nodes.size() && nodes[k + 1] <= s) ++k;
            p.pivot[s] = current[s].translation();
            p.k0[s] = static_cast<int>(k);
            p.k1[s] = static_cast<int>(k);
            p.alpha[s] = 0.0;
            if (s > nodes[k] && k + 1 < nodes.size()) {
                p.k1[s] = static_cast<int>(k + 1);
                p.alpha[s] = (in.t_s[s] - in.t_s[nodes[k]]) /
                             std::max(in.t_s[nodes[k + 1]] - in.t_s[nodes[k]], 1e-9);
            }
        }
    }
    return p;
}

StageOutcome RunRigidStage(const Input& in,
                           std::vector<Block>& blocks,
                           const std::vector<std::uint32_t>& slice_block,
                           const SlamConfig& cfg,
                           const SlamProgress& progress,
                           std::vector<Pose>& current,
                           double* best_score,
                           SlamResult& res) {
    // Stage 1: rigid sections (RigidParam).
    StageOutcome rigid;
    rigid.termination = SlamTermination::kConverged;
    if (cfg.rigid_iterations > 0) {
        Param p = RigidParam(in, current, blocks, cfg);
        if (cfg.coarse_search_m > 0) {
            const auto t0 = Clock::now();
            const std::vector<Eigen::Vector3d> shift =
                CoarseSectionSearch(in, current, blocks, cfg, &res.sections);
            for (const SlamSection& sec : res.sections) {
                res.num_sections_searched += sec.searched ? 1 : 0;
                res.num_sections_shifted += sec.shifted ? 1 : 0;
            }
            for (std::size_t b = 0; b < blocks.size(); ++b) p.tc[b] = shift[b];
            res.timings.coarse_search_s = Seconds(t0);
        }
        // Coarse to fine from 3 INS sigmas (the largest section median), within
        // [max_pair_distance_m, rigid_max_pair_distance_m]: no wide search where GNSS was good.
        double sigma_max = 0;
        for (const Block& b : blocks) {
            std::vector<double> sg;
            for (std::size_t s = b.s0; s < b.s1; ++s) {
                sg.push_back(std::max(in.sigma[s](3), in.sigma[s](4)));
            }
            std::nth_element(
                sg.begin(), sg.begin() + static_cast<std::ptrdiff_t>(sg.size() / 2), sg.end());
            sigma_max = std::max(sigma_max, sg[sg.size() / 2]);
        }
        const double d0 =
            std::clamp(3.0 * sigma_max, cfg.max_pair_distance_m, cfg.rigid_max_pair_distance_m);
        rigid = RunStage(in,
                         p,
                         SlamStage::kRigid,
                         cfg.rigid_iterations,
                         d0,
                         blocks,
                         slice_block,
                         cfg,
                         progress,
                         best_score,
                         res);
        res.rigid_iterations = rigid.iterations;
        res.num_section_links = rigid.num_links;
        current = SlicePoses(p);
    }
    return rigid;
}

}  // namespace pitmap::proc::slam::detail
