// SPDX-License-Identifier: MIT
#include "tools/eval/change_scores.hpp"

#include <algorithm>
#include <cmath>
#include <map>

#include "tools/sim/terrain_change.hpp"

namespace pitmap::eval {

ChangeScore ScoreChange(const std::vector<DodNode>& nodes,
                        const std::vector<RegionInfo>& regions,
                        const std::vector<sim::ChangePart>& parts,
                        double buffer_m) {
    ChangeScore s;
    std::map<int, const RegionInfo*> by_id;
    for (const RegionInfo& r : regions) by_id[r.id] = &r;
    // Nodes of each region on each part (same sign only), and the truth masks.
    std::map<int, std::vector<std::size_t>> on_part;  // region id -> count per part
    std::vector<std::size_t> truth_nodes(parts.size(), 0);
    std::size_t flagged_far = 0;
    const double offsets[9][2] = {{0, 0},
                                  {buffer_m, 0},
                                  {-buffer_m, 0},
                                  {0, buffer_m},
                                  {0, -buffer_m},
                                  {buffer_m, buffer_m},
                                  {-buffer_m, buffer_m},
                                  {buffer_m, -buffer_m},
                                  {-buffer_m, -buffer_m}};
    for (const DodNode& n : nodes) {
        bool near = false;
        for (std::size_t p = 0; p < parts.size(); ++p) {
            if (parts[p].Profile(n.world.x(), n.world.y()) > 0) ++truth_nodes[p];
            for (const auto& o : offsets) {
                if (parts[p].Profile(n.world.x() + o[0], n.world.y() + o[1]) > 0) near = true;
            }
        }
        if (!near) {
            ++s.stable_nodes;
            if (n.region != 0) ++flagged_far;
        }
        if (n.region == 0) continue;
        auto& counts = on_part[n.region];
        counts.resize(parts.size(), 0);
        const auto it = by_id.find(n.region);
        if (it == by_id.end()) continue;
        for (std::size_t p = 0; p < parts.size(); ++p) {
            const int sign = parts[p].thickness_m > 0 ? 1 : -1;
            if (sign == it->second->sign && parts[p].Profile(n.world.x(), n.world.y()) > 0)
                ++counts[p];
        }
    }
    s.stable_flagged_share =
        s.stable_nodes > 0 ? static_cast<double>(flagged_far) / static_cast<double>(s.stable_nodes)
                           : 0.0;
    // Each region to the part holding most of its nodes.
    std::map<int, int> region_part;
    for (const auto& [id, counts] : on_part) {
        const auto best = std::max_element(counts.begin(), counts.end());
        if (best == counts.end() || *best == 0) {
            ++s.false_regions;
            continue;
        }
        region_part[id] = static_cast<int>(best - counts.begin());
    }
    for (std::size_t p = 0; p < parts.size(); ++p) {
        PartScore ps;
        ps.name = parts[p].name;
        ps.volume_true_m3 = parts[p].AnalyticVolume();
        std::size_t inter = 0, detected = 0;
        // The detectable part: the true change along the normal at or above the node's LoD95;
        // the taper below it counts on neither side of the detectable IoU.
        std::size_t below = 0, inter_d = 0, union_d = 0;
        for (const auto& [id, part] : region_part) {
            if (part != static_cast<int>(p)) continue;
            const RegionInfo* r = by_id.at(id);
            ps.volume_detected_m3 += r->volume_m3;
            ps.u95_m3 += r->u95_m3;
            ++ps.regions;
        }
        for (const DodNode& n : nodes) {
            const auto it = region_part.find(n.region);
            const bool det = it != region_part.end() && it->second == static_cast<int>(p);
            const double f = parts[p].Profile(n.world.x(), n.world.y());
            detected += det;
            inter += det && f > 0;
            const bool taper =
                f > 0 && std::abs(parts[p].thickness_m * f) * n.normal_cos < n.lod95_m;
            below += taper;
            if (taper) continue;
            inter_d += det && f > 0;
            union_d += det || f > 0;
        }
        const double uni = static_cast<double>(detected + truth_nodes[p] - inter);
        ps.iou = uni > 0 ? static_cast<double>(inter) / uni : 0.0;
        ps.iou_detectable = union_d > 0 ? static_cast<double>(inter_d) / union_d : 0.0;
        ps.truth_below_lod_share =
            truth_nodes[p] > 0 ? static_cast<double>(below) / truth_nodes[p] : 0.0;
        const double err = ps.volume_detected_m3 - ps.volume_true_m3;
        ps.error_pct = 100.0 * err / std::abs(ps.volume_true_m3);
        ps.within = std::abs(err) <= std::max(0.05 * std::abs(ps.volume_true_m3), ps.u95_m3);
        ps.contained = std::abs(err) <= ps.u95_m3;
        s.parts.push_back(ps);
    }
    return s;
}

}  // namespace pitmap::eval
