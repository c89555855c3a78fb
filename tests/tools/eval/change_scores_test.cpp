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

// A paraboloid hollow 1 m deep on a 60 deg face (the change along the normal half the vertical)
// with a LoD95 of 0.1 m: the rim where 0.5 q < 0.1 (q < 0.2, a fifth of the outline's area)
// lies below detection. A detection of exactly the rest is perfect against the detectable
// part but near 0.8 against the whole outline; a detection reaching into that rim is not held
// against it; one reaching past the outline is.
TEST(ChangeScores, TheTaperBelowDetectionIsLeftOutOfTheDetectableIou) {
    sim::ChangePart scar{"scar", "scar", sim::ChangeShape::kParaboloid, 0, 0, 0, 4.0, 2.0, 0, -1.0};
    const double cos60 = 0.5, lod = 0.1;
    const auto detectable = [&](double x, double y) {
        return std::abs(scar.thickness_m * scar.Profile(x, y)) * cos60 >= lod;
    };
    const auto score = [&](double scale) {
        std::vector<DodNode> nodes;
        for (double y = -6; y <= 6; y += 0.05) {
            for (double x = -6; x <= 6; x += 0.05) {
                DodNode n;
                n.world = {x, y};
                n.normal_cos = cos60;
                n.lod95_m = lod;
                const double r = std::hypot(x / (4.0 * scale), y / (2.0 * scale));
                // The detectable ellipse is q >= 0.2: sqrt(0.8) of the outline's (scale 1).
                if (detectable(x, y) || r * r <= 0.8) n.region = 1;
                nodes.push_back(n);
            }
        }
        return ScoreChange(nodes, {{1, -1, scar.AnalyticVolume(), 1.0}}, {scar}).parts.at(0);
    };
    const PartScore exact = score(1.0);
    EXPECT_NEAR(exact.truth_below_lod_share, 0.2, 0.01);
    EXPECT_NEAR(exact.iou, 0.8, 0.01);             // the rim counted as missed
    EXPECT_NEAR(exact.iou_detectable, 1.0, 1e-9);  // the rim left out
    const PartScore into_rim = score(1.08);  // into the rim (0.97 of the outline), not past it
    EXPECT_NEAR(into_rim.iou_detectable, 1.0, 1e-9);
    EXPECT_GT(into_rim.iou, exact.iou);
    const PartScore past = score(1.5);  // 1.34 of the outline: the ring past it counts
    EXPECT_LT(past.iou_detectable, 0.6);
    // Without a stated LoD every changed node is detectable: the two IoUs agree.
    std::vector<DodNode> plain;
    for (double y = -6; y <= 6; y += 0.1) {
        for (double x = -6; x <= 6; x += 0.1) {
            DodNode n;
            n.world = {x, y};
            n.region = detectable(x, y) ? 1 : 0;
            plain.push_back(n);
        }
    }
    const PartScore p = ScoreChange(plain, {{1, -1, 1.0, 1.0}}, {scar}).parts.at(0);
    EXPECT_NEAR(p.iou_detectable, p.iou, 1e-12);
    EXPECT_EQ(p.truth_below_lod_share, 0.0);
}

}  // namespace
}  // namespace pitmap::eval
