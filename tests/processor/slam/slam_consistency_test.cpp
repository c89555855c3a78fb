// SPDX-License-Identifier: MIT
// The consistency score (plane-fit RMS over cells shared by passes t_d apart) is a property of
// the geometry, not of where the survey's origin lies: the same two passes give the same score
// at any height. Raw sums of z^2 lose the millimetre residuals at large |z|.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "processor/slam/internal.hpp"

namespace pitmap::proc::slam::detail {
namespace {

// Two passes 100 s apart over one 2 m x 2 m tilted plane (z = 0.1 x - 0.05 y), 1 mm noise, the
// world placed at height z_offset_m.
Input TwoPassesOverAPlane(double z_offset_m) {
    Input in;
    std::mt19937 rng(7);
    std::normal_distribution<float> noise(0.0f, 0.001f);
    for (int pass = 0; pass < 2; ++pass) {
        in.input_index.push_back(static_cast<std::size_t>(pass));
        in.t_s.push_back(100.0 * pass);
        Pose T = Pose::Identity();
        T.translation() = Eigen::Vector3d(0, 0, z_offset_m);
        in.T_ins.push_back(T);
        in.sigma.push_back(Vector6d::Constant(0.01));
        in.offset.push_back(in.points.size());
        for (int i = 0; i < 40; ++i) {
            for (int j = 0; j < 40; ++j) {
                const float x = 0.05f * static_cast<float>(i) + 0.01f * static_cast<float>(pass);
                const float y = 0.05f * static_cast<float>(j);
                in.points.emplace_back(x, y, 0.1f * x - 0.05f * y + noise(rng));
            }
        }
    }
    in.offset.push_back(in.points.size());
    return in;
}

TEST(SlamConsistency, ScoreDoesNotDependOnTheHeightOfTheOrigin) {
    SlamConfig cfg;
    cfg.query_stride = 1;
    cfg.score_cell_m = 0.5;
    cfg.min_time_separation_s = 30.0;

    const Input near = TwoPassesOverAPlane(0.0);
    const double score = ConsistencyScore(near, near.T_ins, cfg);
    // 1 mm noise per point, planes fitted with 3 parameters per cell: the score is that noise.
    ASSERT_GT(score, 0.0008);
    ASSERT_LT(score, 0.0012);

    for (const double z : {-450.0, 1.0e4, 5.0e5}) {
        const Input far = TwoPassesOverAPlane(z);
        EXPECT_NEAR(ConsistencyScore(far, far.T_ins, cfg), score, 1e-3 * score) << "z " << z;
        const Consistency by_slice = ConsistencyBySlice(far, far.T_ins, cfg);
        EXPECT_NEAR(by_slice.score_m, score, 1e-3 * score) << "z " << z;
        ASSERT_EQ(by_slice.by_slice_m.size(), 2u);
        for (const double v : by_slice.by_slice_m) {
            EXPECT_GT(v, 0.0008) << "z " << z;
            EXPECT_LT(v, 0.0012) << "z " << z;
        }
    }
}

}  // namespace
}  // namespace pitmap::proc::slam::detail
