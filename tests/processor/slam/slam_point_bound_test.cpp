// SPDX-License-Identifier: MIT
// The points each pass contributes to SLAM, bounded per cell (BoundPointsPerCell, decision
// 036): per section and per cube of the world frame (by the slices' poses), the first
// per_cell finite points in time order are kept, the rest dropped; sections are counted apart.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <random>
#include <tuple>
#include <vector>

#include "processor/slam/internal.hpp"

namespace pitmap::proc::slam::detail {
namespace {

std::vector<const std::vector<Eigen::Vector3f>*> Pointers(
    const std::vector<std::vector<Eigen::Vector3f>>& points) {
    std::vector<const std::vector<Eigen::Vector3f>*> out;
    for (const auto& p : points) out.push_back(&p);
    return out;
}

Pose Shifted(double x) {
    Pose T = Pose::Identity();
    T.translation() = Eigen::Vector3d(x, 0, 0);
    return T;
}

// Three slices in one cube (0.25 m cubes), then a second section with two more.
TEST(SlamPointBound, KeepsTheFirstPointsOfEachPassInACube) {
    const float nan = std::nanf("");
    std::vector<std::vector<Eigen::Vector3f>> points = {
        {{0.01f, 0.01f, 0.01f}, {0.02f, 0.02f, 0.02f}, {0.30f, 0.0f, 0.0f}},
        {{nan, 0.0f, 0.0f}, {0.03f, 0.03f, 0.03f}},
        // Moved by its pose into the first cube: counted with it.
        {{-0.96f, 0.1f, 0.1f}},
        {{0.05f, 0.05f, 0.05f}, {0.06f, 0.06f, 0.06f}, {0.07f, 0.07f, 0.07f}},
        {{0.08f, 0.08f, 0.08f}}};
    const std::vector<Pose> T = {Shifted(0), Shifted(0), Shifted(1.0), Shifted(0), Shifted(0)};
    const std::vector<std::size_t> sections = {0, 3, 5};
    const auto keep = BoundPointsPerCell(Pointers(points), T, sections, 0.25, 2);
    // Finite points only, slice by slice: 3 + 1 + 1 + 3 + 1.
    const std::vector<std::uint8_t> want = {1, 1, 1, 0, 0, 1, 1, 0, 0};
    EXPECT_EQ(keep, want);
    // Cubes of 0 keep every finite point; so does a bound no cube reaches.
    EXPECT_EQ(BoundPointsPerCell(Pointers(points), T, sections, 0.0, 1),
              std::vector<std::uint8_t>(9, 1));
    EXPECT_EQ(BoundPointsPerCell(Pointers(points), T, sections, 0.25, 5),
              std::vector<std::uint8_t>(9, 1));
}

// Random slices in random sections: per section and cube, exactly min(count, bound) points are
// kept, and they are the first ones in time order.
TEST(SlamPointBound, EachPassKeepsAtMostTheBoundPerCube) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> u(-2.0f, 2.0f);
    std::vector<std::vector<Eigen::Vector3f>> points(60);
    std::vector<Pose> T;
    for (std::size_t s = 0; s < points.size(); ++s) {
        for (int i = 0; i < 40; ++i) points[s].emplace_back(u(rng), u(rng), 0.1f * u(rng));
        T.push_back(Shifted(0.05 * static_cast<double>(s)));
    }
    const std::vector<std::size_t> sections = {0, 7, 20, 21, 45, 60};
    const double cell = 0.5;
    for (int bound : {1, 3}) {
        const auto keep = BoundPointsPerCell(Pointers(points), T, sections, cell, bound);
        ASSERT_EQ(keep.size(), points.size() * 40);
        std::size_t k = 0, kept = 0;
        for (std::size_t i = 0; i + 1 < sections.size(); ++i) {
            std::map<std::tuple<long, long, long>, int> seen;
            for (std::size_t s = sections[i]; s < sections[i + 1]; ++s) {
                for (const auto& x : points[s]) {
                    const Eigen::Vector3d p = T[s] * x.cast<double>();
                    const auto key = std::make_tuple(std::lround(std::floor(p.x() / cell)),
                                                     std::lround(std::floor(p.y() / cell)),
                                                     std::lround(std::floor(p.z() / cell)));
                    const int n = seen[key]++;
                    EXPECT_EQ(keep[k], n < bound ? 1 : 0) << "section " << i << " slice " << s;
                    kept += keep[k++];
                }
            }
        }
        EXPECT_LT(kept, keep.size());  // the bound does thin these
    }
}

// Sections flagged every_point keep every point however full their cubes (decision 048: a GNSS
// outage's sections); the flags come from the INS's horizontal sigma, east or north, at any slice.
TEST(SlamPointBound, SectionsWhoseInsSigmaExceedsTheGateKeepEveryPoint) {
    std::vector<std::vector<Eigen::Vector3f>> points(4, std::vector<Eigen::Vector3f>(3));
    for (auto& slice : points) {
        for (std::size_t i = 0; i < slice.size(); ++i)
            slice[i] = Eigen::Vector3f(0.01f * static_cast<float>(i), 0.0f, 0.0f);
    }
    const std::vector<Pose> T(4, Pose::Identity());
    const std::vector<std::size_t> sections = {0, 2, 4};
    // One cube, one point a section: 1 of 6 kept in each unflagged section.
    const std::vector<std::uint8_t> bounded = {1, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0};
    EXPECT_EQ(BoundPointsPerCell(Pointers(points), T, sections, 0.25, 1), bounded);
    std::vector<std::uint8_t> second_whole = bounded;
    std::fill(second_whole.begin() + 6, second_whole.end(), 1);
    EXPECT_EQ(BoundPointsPerCell(Pointers(points), T, sections, 0.25, 1, {0, 1}), second_whole);

    Input in;
    in.sigma.assign(4, Vector6d::Constant(0.01));
    in.sigma[3](4) = 0.8;  // north, in the second section's last slice
    EXPECT_EQ(SectionsKeepingEveryPoint(in, sections, 0.05), (std::vector<char>{0, 1}));
    EXPECT_EQ(SectionsKeepingEveryPoint(in, sections, 1.0), (std::vector<char>{0, 0}));
    in.sigma[0](3) = 0.06;  // east, in the first section
    EXPECT_EQ(SectionsKeepingEveryPoint(in, sections, 0.05), (std::vector<char>{1, 1}));
    EXPECT_EQ(SectionsKeepingEveryPoint(in, sections, 0.0), (std::vector<char>{0, 0}));
}

}  // namespace
}  // namespace pitmap::proc::slam::detail
