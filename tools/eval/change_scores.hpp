// SPDX-License-Identifier: MIT
// Scores of `pitmap compare` (a compare folder: dod.tif, compare.json) against the changes a
// repeat survey's truth holds (tools/sim/terrain_change.hpp, truth/changes.json):
//   per true part (slump_scar, slump_toe, backfill, spill, cut, ...): the regions of its sign
//   whose nodes lie mostly on it are its detection; volume_detected (their volumes summed),
//   u95 (their U95 summed), error_pct against the exact volume, within (|error| <= max(5 %,
//   u95): the target), contained (|error| <= u95), iou (the detection's nodes against
//   the nodes where the part changes the terrain, over the compared nodes), iou_detectable
//   (the same against the part's detectable nodes, where its true change along the surface's
//   normal reaches the node's LoD95; the taper below it is left out of both sides, neither
//   asked for nor held against a detection: decision 023, section 5), truth_below_lod_share
//   (of the part's nodes, those below their LoD95);
//   stable_flagged_share: nodes in any region more than buffer_m from every part's outline,
//   over the compared nodes that far from every part; false_regions: regions on no part.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "tools/sim/scenario.hpp"

namespace pitmap::eval {

struct DodNode {
    Eigen::Vector2d world = Eigen::Vector2d::Zero();  // the node in the truth's world frame
    int region = 0;                                   // 0 = none
    double normal_cos = 1.0;  // |cos| of the surface's normal to the vertical there (1: a DEM)
    double lod95_m = 0;       // the node's level of detection at 95 % (0: none stated)
};

struct RegionInfo {
    int id = 0;
    int sign = 0;  // +1 fill, -1 cut
    double volume_m3 = 0, u95_m3 = 0;
};

struct PartScore {
    std::string name;
    double volume_true_m3 = 0, volume_detected_m3 = 0, u95_m3 = 0, error_pct = 0, iou = 0;
    double iou_detectable = 0, truth_below_lod_share = 0;
    int regions = 0;
    bool within = false, contained = false;
};

struct ChangeScore {
    std::vector<PartScore> parts;
    double stable_flagged_share = 0;
    std::size_t stable_nodes = 0;
    int false_regions = 0;
};

ChangeScore ScoreChange(const std::vector<DodNode>& nodes,
                        const std::vector<RegionInfo>& regions,
                        const std::vector<sim::ChangePart>& parts,
                        double buffer_m = 0.5);

}  // namespace pitmap::eval
