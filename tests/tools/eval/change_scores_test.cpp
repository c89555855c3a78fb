// SPDX-License-Identifier: MIT
// pitmap-eval's change scores (tools/eval/change_scores.hpp) on a detection made by hand: a
// region exactly on a heap, one on half a cut, a false one far from both.
#include "tools/eval/change_scores.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace pitmap::eval {
namespace {

TEST(ChangeScores, VolumeIouAndStableFlaggedOfAHandMadeDetection) {
    sim::ChangePart heap{"heap", "heap", sim::ChangeShape::kFrustum, -5, 0, 0, 1.0, 2.0, 0, 0.5};
    sim::ChangePart cut{"cut", "cut", sim::ChangeShape::kBox, 5, 0, 0, 1.0, 1.0, 0.5, -0.3};
    std::vector<DodNode> nodes;
    int heap_nodes = 0, cut_nodes = 0, cut_east = 0;
    for (double y = -10; y <= 10; y += 0.1) {
        for (double x = -10; x <= 10; x += 0.1) {
            DodNode n;
            n.world = {x, y};
            if (heap.Profile(x, y) > 0) {
                n.region = 1;
                ++heap_nodes;
            }
            if (cut.Profile(x, y) > 0) {
                ++cut_nodes;
                if (x > 5) {
                    n.region = 2;  // only the cut's eastern half detected
                    ++cut_east;
                }
            }
            if (std::hypot(x, y - 8) < 0.3) n.region = 3;  // noise far from both
            nodes.push_back(n);
        }
    }
    const std::vector<RegionInfo> regions = {
        {1, 1, heap.AnalyticVolume() * 1.03, 0.1},  // 3 % over, U95 small
        {2, -1, cut.AnalyticVolume() * 0.5, 0.2},   // half the cut
        {3, 1, 0.01, 0.01}};
    const ChangeScore s = ScoreChange(nodes, regions, {heap, cut});
    ASSERT_EQ(s.parts.size(), 2u);
    EXPECT_EQ(s.parts[0].name, "heap");
    EXPECT_NEAR(s.parts[0].iou, 1.0, 1e-12);
    EXPECT_NEAR(s.parts[0].error_pct, 3.0, 1e-9);
    EXPECT_TRUE(s.parts[0].within);      // within 5 %
    EXPECT_FALSE(s.parts[0].contained);  // but not within its U95
    EXPECT_NEAR(s.parts[1].iou, static_cast<double>(cut_east) / cut_nodes, 1e-12);
    EXPECT_NEAR(s.parts[1].error_pct, 50.0, 1e-9);  // half the loss: +50 % (less cut)
    EXPECT_FALSE(s.parts[1].within);
    EXPECT_EQ(s.false_regions, 1);
    EXPECT_GT(s.stable_flagged_share, 0.0);
    EXPECT_LT(s.stable_flagged_share, 0.01);
    EXPECT_GT(heap_nodes, 1000);
}

}  // namespace
}  // namespace pitmap::eval
