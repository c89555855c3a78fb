// SPDX-License-Identifier: MIT
// TsdfVolume::Integrate into a volume that already holds leaves: the volume's leaves are moved
// into the slabs a call touches and back, never copied (the leaf objects of the first call are
// the volume's after any later one, where their slab was touched and where it was not), and
// the volume is the one of a single call voxel for voxel. docs/decisions/040.
#include "processor/fusion/tsdf.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cstddef>
#include <map>
#include <utility>
#include <vector>

#include <openvdb/openvdb.h>

#include "processor/fusion/detail/tsdf_grids.hpp"
#include "tests/processor/fusion/synthetic_scans.hpp"

namespace pitmap::proc::fusion {
namespace {

using LeafT = openvdb::FloatTree::LeafNodeType;

// Each leaf of `tree` by origin: the object and the sum of its values (to tell whether a call
// updated it).
struct LeafRecord {
    const LeafT* leaf;
    double sum;
};
std::map<std::array<int, 3>, LeafRecord> Leaves(const openvdb::FloatTree& tree) {
    std::map<std::array<int, 3>, LeafRecord> out;
    for (auto it = tree.cbeginLeaf(); it; ++it) {
        double sum = 0.0;
        for (auto v = it->cbeginValueAll(); v; ++v) sum += static_cast<double>(*v);
        out[{it->origin().x(), it->origin().y(), it->origin().z()}] = {&*it, sum};
    }
    return out;
}

// How many of `before`'s leaves are still the same objects in `tree` at their origin, and how
// many of those hold other values now.
std::pair<std::size_t, std::size_t> KeptAndChanged(
    const std::map<std::array<int, 3>, LeafRecord>& before, const openvdb::FloatTree& tree) {
    const auto now = Leaves(tree);
    std::size_t kept = 0, changed = 0;
    for (const auto& [origin, rec] : before) {
        const auto it = now.find(origin);
        if (it == now.end() || it->second.leaf != rec.leaf) continue;
        ++kept;
        if (it->second.sum != rec.sum) ++changed;
    }
    return {kept, changed};
}

std::map<std::array<int, 3>, std::pair<float, float>> Voxels(const TsdfVolume& v) {
    std::map<std::array<int, 3>, std::pair<float, float>> out;
    v.ForEachVoxel([&](const Eigen::Vector3i& ijk, float d, float w) {
        out[{ijk.x(), ijk.y(), ijk.z()}] = {d, w};
    });
    return out;
}

TEST(TsdfVolume, LaterIntegrateCallsMoveTheVolumesLeavesNotCopyThem) {
    testing::SyntheticWorld world;
    world.plane_z_m = -4.0;
    world.spheres.push_back({Eigen::Vector3d(-2.0, 0.0, -3.6), 0.6});
    testing::LineSurvey survey;
    survey.x0_m = -8.0;  // slabs of 6.4 m at 0.1 m voxels: four of them along x
    survey.x1_m = 8.0;
    survey.spacing_m = 0.1;
    survey.lines_y_m = {-0.5, 0.5};
    survey.num_beams = 121;
    survey.start_angle_rad = -30.0 * std::numbers::pi / 180.0;
    survey.increment_rad = 0.5 * std::numbers::pi / 180.0;
    survey.noise_sigma_m = 0.02;
    const std::vector<SonarScan> scans = testing::MakeScans(world, survey);
    const std::size_t line = scans.size() / 2;
    TsdfConfig config;
    config.truncation_m = 0.5;
    config.max_weight = 20.0f;

    TsdfVolume once(config);
    once.Integrate(scans);
    TsdfVolume v(config);
    // The first line; then the second line's western half (its slabs touched again, the
    // eastern ones not); then the rest.
    const std::vector<std::size_t> cuts = {0, line, line + line / 2, scans.size()};
    std::map<std::array<int, 3>, LeafRecord> d_before, w_before;
    for (std::size_t c = 0; c + 1 < cuts.size(); ++c) {
        v.Integrate(scans, cuts[c], cuts[c + 1]);
        if (c > 0) {
            const auto [d_kept, d_changed] = KeptAndChanged(d_before, v.impl().distance->tree());
            const auto [w_kept, w_changed] = KeptAndChanged(w_before, v.impl().weight->tree());
            EXPECT_EQ(d_kept, d_before.size()) << "call " << c;
            EXPECT_EQ(w_kept, w_before.size()) << "call " << c;
            // Leaves the call updated (their slab touched) and leaves it did not.
            EXPECT_GT(w_changed, 0u) << "call " << c;
            EXPECT_LT(w_changed, w_kept) << "call " << c;
            EXPECT_GT(d_changed, 0u) << "call " << c;
        }
        d_before = Leaves(v.impl().distance->tree());
        w_before = Leaves(v.impl().weight->tree());
        ASSERT_GT(w_before.size(), 100u);
    }
    EXPECT_TRUE(Voxels(v) == Voxels(once));
    EXPECT_EQ(v.Stats().active_voxels, once.Stats().active_voxels);
    EXPECT_EQ(v.impl().distance->getName(), "tsdf");
    EXPECT_EQ(v.impl().weight->getName(), "weight");
    EXPECT_EQ(v.impl().distance->voxelSize(), once.impl().distance->voxelSize());
}

}  // namespace
}  // namespace pitmap::proc::fusion
