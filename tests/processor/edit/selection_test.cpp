// SPDX-License-Identifier: MIT
// The selection of pitmap edit (processor/edit/selection.hpp): point in polygon (convex,
// concave, self-crossing, shared edges counted once), boxes, the projection (column-major
// matrices as three.js sends them, points behind the camera, the near and far planes of an
// orthographic slab), the selection over many points against a brute force with 1, 2 and all
// threads, the query's validation; and EffectiveStatus against survey::Resolve for every
// automatic status and hand edit.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "processor/edit/edit_session.hpp"
#include "processor/edit/selection.hpp"

namespace pitmap::proc::edit {
namespace {

std::array<double, 16> Identity() {
    return {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
}

TEST(InsidePolygon, ConvexAndConcave) {
    const auto square = BoxPolygon({-0.5, -0.5}, {0.5, 0.5});
    EXPECT_TRUE(InsidePolygon(square, 0, 0));
    EXPECT_FALSE(InsidePolygon(square, 0.6, 0));
    EXPECT_FALSE(InsidePolygon(square, 0, -0.51));
    // A U shape: the notch between its arms is outside.
    const std::vector<NdcPoint> u = {
        {0, 0}, {3, 0}, {3, 3}, {2, 3}, {2, 1}, {1, 1}, {1, 3}, {0, 3}};
    EXPECT_TRUE(InsidePolygon(u, 0.5, 2));
    EXPECT_TRUE(InsidePolygon(u, 2.5, 2));
    EXPECT_FALSE(InsidePolygon(u, 1.5, 2));
    EXPECT_TRUE(InsidePolygon(u, 1.5, 0.5));
}

TEST(InsidePolygon, SelfCrossingLassoIsEvenOdd) {
    // A bow tie: both lobes inside, outside above and below the crossing.
    const std::vector<NdcPoint> bow = {{0, 0}, {2, 2}, {2, 0}, {0, 2}};
    EXPECT_TRUE(InsidePolygon(bow, 0.2, 1));
    EXPECT_TRUE(InsidePolygon(bow, 1.8, 1));
    EXPECT_FALSE(InsidePolygon(bow, 1, 1.8));
    EXPECT_FALSE(InsidePolygon(bow, 1, 0.2));
    // A loop drawn twice around the same area encloses nothing by the even-odd rule.
    const std::vector<NdcPoint> twice = {
        {0, 0}, {1, 0}, {1, 1}, {0, 1}, {0, 0}, {1, 0}, {1, 1}, {0, 1}};
    EXPECT_FALSE(InsidePolygon(twice, 0.5, 0.5));
}

TEST(InsidePolygon, SharedEdgeCountsOnce) {
    const auto left = BoxPolygon({0, 0}, {1, 1});
    const auto right = BoxPolygon({1, 0}, {2, 1});
    for (double y : {0.0, 0.25, 0.5, 0.999}) {
        EXPECT_NE(InsidePolygon(left, 1.0, y), InsidePolygon(right, 1.0, y)) << y;
    }
    const auto top = BoxPolygon({0, 1}, {1, 2});
    EXPECT_NE(InsidePolygon(left, 0.5, 1.0), InsidePolygon(top, 0.5, 1.0));
}

TEST(InsidePolygon, DegeneratePolygonsHoldNothing) {
    EXPECT_FALSE(InsidePolygon({{0, 0}, {1, 1}, {2, 2}}, 1, 1));
    EXPECT_FALSE(InsidePolygon({{0, 0}, {0, 0}, {0, 0}}, 0, 0));
    EXPECT_FALSE(InsidePolygon(BoxPolygon({0.3, 0.3}, {0.3, 0.9}), 0.3, 0.5));
}

TEST(Project, ColumnMajorTranslationAndW) {
    auto m = Identity();
    m[12] = 0.5;  // x += 0.5 (column 3, row 0)
    Projected p = Project(m, 0.1, 0.2, 0.3);
    EXPECT_TRUE(p.in_view);
    EXPECT_NEAR(p.x, 0.6, 1e-12);
    EXPECT_NEAR(p.y, 0.2, 1e-12);
    // A perspective: w = -z (three.js looks down -z); a point behind the camera (z > 0) is
    // never in view, even though x/w, y/w may land inside a polygon.
    const double f = 1, nr = 1, fr = 100;
    std::array<double, 16> persp = {f,
                                    0,
                                    0,
                                    0,
                                    0,
                                    f,
                                    0,
                                    0,
                                    0,
                                    0,
                                    -(fr + nr) / (fr - nr),
                                    -1,
                                    0,
                                    0,
                                    -2 * fr * nr / (fr - nr),
                                    0};
    EXPECT_TRUE(Project(persp, 0, 0, -10).in_view);
    EXPECT_FALSE(Project(persp, 0, 0, 10).in_view);
    EXPECT_FALSE(Project(persp, 0, 0, -0.5).in_view);  // before the near plane
    EXPECT_FALSE(Project(persp, 0, 0, -200).in_view);  // past the far plane
    EXPECT_FALSE(Project(persp, std::numeric_limits<double>::quiet_NaN(), 0, -10).in_view);
}

TEST(Project, OrthographicSlab) {
    // An orthographic camera looking down -z, near 9, far 11 (a 2 m slab around z = -10).
    const double nr = 9, fr = 11;
    std::array<double, 16> ortho = {
        0.1, 0, 0, 0, 0, 0.1, 0, 0, 0, 0, -2 / (fr - nr), 0, 0, 0, -(fr + nr) / (fr - nr), 1};
    EXPECT_TRUE(Project(ortho, 0, 0, -10).in_view);
    EXPECT_TRUE(Project(ortho, 3, -2, -9.01).in_view);
    EXPECT_FALSE(Project(ortho, 0, 0, -8.9).in_view);
    EXPECT_FALSE(Project(ortho, 0, 0, -11.1).in_view);
}

TEST(SelectInPolygon, MatchesBruteForceWithAnyThreadCount) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> u(-2, 2);
    const std::size_t n = 300000;
    std::vector<float> xyz(3 * n);
    for (auto& v : xyz) v = u(rng);
    xyz[3 * 17] = std::numeric_limits<float>::quiet_NaN();
    SelectionQuery q;
    q.view_projection = Identity();
    q.view_projection[5] = 0.8;  // y scaled
    q.polygon = {{-0.9, -0.8}, {0.7, -0.6}, {0.1, 0.0}, {0.8, 0.9}, {-0.5, 0.6}};
    ASSERT_TRUE(q.Validate().empty());
    std::vector<std::uint32_t> want;
    for (std::size_t i = 0; i < n; ++i) {
        const Projected p = Project(q.view_projection, xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
        if (p.in_view && InsidePolygon(q.polygon, p.x, p.y))
            want.push_back(static_cast<std::uint32_t>(i));
    }
    ASSERT_GT(want.size(), 10000u);
    for (int threads : {1, 2, 0}) {
        EXPECT_EQ(SelectInPolygon(xyz.data(), n, q, {}, threads), want) << threads;
    }
    // An eligibility test keeps a subset.
    const auto even = SelectInPolygon(xyz.data(), n, q, [](std::size_t i) { return i % 2 == 0; });
    std::vector<std::uint32_t> want_even;
    for (auto i : want) {
        if (i % 2 == 0) want_even.push_back(i);
    }
    EXPECT_EQ(even, want_even);
    EXPECT_TRUE(SelectInPolygon(xyz.data(), 0, q).empty());
}

TEST(SelectionQuery, Validate) {
    SelectionQuery q;
    q.view_projection = Identity();
    q.polygon = {{0, 0}, {1, 0}};
    EXPECT_EQ(q.Validate().size(), 1u);
    q.polygon.push_back({1, std::numeric_limits<double>::infinity()});
    EXPECT_EQ(q.Validate().size(), 1u);
    q.polygon.back().y = 1;
    EXPECT_TRUE(q.Validate().empty());
    q.view_projection[3] = std::numeric_limits<double>::quiet_NaN();
    EXPECT_EQ(q.Validate().size(), 1u);
    q.view_projection[3] = 0;
    q.polygon.assign(kMaxPolygonVertices + 1, {0, 0});
    EXPECT_EQ(q.Validate().size(), 1u);
}

TEST(EffectiveStatus, IsResolve) {
    using survey::ManualEdit;
    using survey::SoundingStatus;
    for (int a = 0; a < survey::kNumSoundingStatus; ++a) {
        const auto automatic = static_cast<SoundingStatus>(a);
        if (automatic == SoundingStatus::kManual) continue;  // never automatic
        for (int m = 0; m < 3; ++m) {
            const auto manual = static_cast<ManualEdit>(m);
            survey::SoundingFlags f;
            const bool cleaning = survey::IsCleaningStatus(automatic);
            f.cleaning = {
                static_cast<std::uint8_t>(cleaning ? automatic : SoundingStatus::kAccepted)};
            f.manual = {static_cast<std::uint8_t>(manual)};
            const SoundingStatus want =
                survey::Resolve(cleaning ? SoundingStatus::kAccepted : automatic, f, 0);
            EXPECT_EQ(EffectiveStatus(automatic, manual), want) << a << " " << m;
        }
    }
}

}  // namespace
}  // namespace pitmap::proc::edit
