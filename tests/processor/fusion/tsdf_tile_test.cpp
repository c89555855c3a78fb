// SPDX-License-Identifier: MIT
// TSDF by tiles (processor/fusion/tsdf.hpp VoxelColumns): volumes restricted to tiles, each
// integrating the whole scan sequence alone, hold the whole volume's voxels of their core voxel
// for voxel, bit for bit (distance and weight), in beam-width and ray mode and with the fan
// tilted so that the rasteriser's columns run horizontally; the tiles' meshes cut by the seam
// rule (KeepTrianglesIn) are the whole mesh's triangles, each in one tile; a tile integrating
// only the pings over it differs (the comparison can fail).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstring>
#include <map>
#include <numbers>
#include <tuple>

#include "processor/fusion/tsdf.hpp"
#include "tests/processor/fusion/synthetic_scans.hpp"

namespace pitmap::proc::fusion {
namespace {

using testing::LineSurvey;
using testing::SyntheticWorld;

constexpr int kTile = kRegionAlignVoxels;  // core size, voxels

using Voxel = std::tuple<int, int, int, std::uint32_t, std::uint32_t>;  // x, y, z, bits of d, w

std::uint32_t Bits(float v) {
    std::uint32_t b;
    std::memcpy(&b, &v, sizeof b);
    return b;
}

int FloorDiv(int a, int b) {
    return a >= 0 ? a / b : -((-a + b - 1) / b);
}

// The voxels of `volume` by tile (FloorDiv of x and y by kTile), sorted.
std::map<std::pair<int, int>, std::vector<Voxel>> VoxelsByTile(const TsdfVolume& volume) {
    std::map<std::pair<int, int>, std::vector<Voxel>> out;
    volume.ForEachVoxel([&](const Eigen::Vector3i& v, float d, float w) {
        out[{FloorDiv(v.x(), kTile), FloorDiv(v.y(), kTile)}].emplace_back(
            v.x(), v.y(), v.z(), Bits(d), Bits(w));
    });
    for (auto& [tile, voxels] : out) std::sort(voxels.begin(), voxels.end());
    return out;
}

VoxelColumns Core(int ti, int tj) {
    return {ti * kTile, ti * kTile + kTile - 1, tj * kTile, tj * kTile + kTile - 1};
}

VoxelColumns Grown(const VoxelColumns& c, int by) {
    return {c.x_min - by, c.x_max + by, c.y_min - by, c.y_max + by};
}

// Mesh triangles as sorted vertex triples (bit patterns), for comparing two meshes as sets.
using Tri = std::array<std::uint32_t, 9>;
std::vector<Tri> Triangles(const TriangleMesh& m) {
    std::vector<Tri> out;
    for (const Eigen::Vector3i& t : m.triangles) {
        Tri tri;
        for (int k = 0; k < 3; ++k) {
            const Eigen::Vector3f& p = m.vertices[static_cast<std::size_t>(t[k])];
            for (int a = 0; a < 3; ++a) tri[static_cast<std::size_t>(3 * k + a)] = Bits(p[a]);
        }
        out.push_back(tri);
    }
    std::sort(out.begin(), out.end());
    return out;
}

struct Scene {
    const char* name;
    TsdfConfig config;
    std::vector<SonarScan> scans;
};

// Three lines over a floor with boulders, spanning several 64-voxel tiles each way.
std::vector<Scene> Scenes() {
    SyntheticWorld world;
    world.plane_z_m = -4.0;
    world.spheres.push_back({Eigen::Vector3d(0.3, 1.1, -3.6), 0.9});
    world.spheres.push_back({Eigen::Vector3d(-2.1, -1.7, -3.3), 1.2});
    LineSurvey survey;
    survey.x0_m = -6.0;
    survey.x1_m = 6.0;
    survey.spacing_m = 0.25;
    survey.lines_y_m = {-4.5, 0.3, 4.8};
    survey.num_beams = 91;
    survey.increment_rad = 1.0 * std::numbers::pi / 180.0;
    survey.noise_sigma_m = 0.02;
    std::vector<Scene> scenes;
    TsdfConfig c;
    c.voxel_size_m = 0.08;  // not a binary fraction: voxel positions round
    c.truncation_m = 0.3;
    c.max_range_m = 30;
    c.num_threads = 2;
    scenes.push_back({"beam_width", c, testing::MakeScans(world, survey)});
    TsdfConfig ray = c;
    ray.sensor_model = SensorModel::kRay;
    scenes.push_back({"ray", ray, testing::MakeScans(world, survey)});
    // Heads pitched and yawed: the fan's columns run along a horizontal world axis, so a
    // column's walk crosses tile edges.
    std::vector<SonarScan> tilted = testing::MakeScans(world, survey);
    testing::Tilt(tilted,
                  world,
                  survey.increment_rad,
                  (Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitZ()) *
                   Eigen::AngleAxisd(1.1, Eigen::Vector3d::UnitY()))
                      .toRotationMatrix());
    scenes.push_back({"tilted", c, tilted});
    return scenes;
}

TEST(TsdfTile, TileCoresEqualTheWholeVolumeVoxelForVoxel) {
    bool first = true;
    for (const Scene& scene : Scenes()) {
        SCOPED_TRACE(scene.name);
        TsdfVolume whole(scene.config);
        whole.Integrate(scene.scans);
        const auto expected = VoxelsByTile(whole);
        ASSERT_GE(expected.size(), 6u);  // the scene spans several tiles
        TsdfVolume assembled(scene.config);
        std::size_t compared = 0;
        for (const auto& [tile, voxels] : expected) {
            const VoxelColumns core = Core(tile.first, tile.second);
            // Overlap of one alignment step, and (first scene) none: the core does not depend
            // on it.
            for (int overlap : {kTile, 0}) {
                if (overlap == 0 && !first) continue;
                TsdfVolume part(scene.config, Grown(core, overlap));
                part.Integrate(scene.scans);
                const auto got = VoxelsByTile(part);
                const auto it = got.find(tile);
                ASSERT_NE(it, got.end());
                EXPECT_EQ(it->second, voxels) << "tile " << tile.first << "," << tile.second;
                for (const auto& [other, v] : got) {
                    // Nothing outside the region.
                    EXPECT_LE(std::abs(other.first - tile.first), overlap / kTile);
                    EXPECT_LE(std::abs(other.second - tile.second), overlap / kTile);
                }
                if (overlap > 0) assembled.CopyColumns(part, core);
            }
            compared += voxels.size();
        }
        EXPECT_EQ(compared, static_cast<std::size_t>(whole.Stats().active_voxels));
        EXPECT_EQ(VoxelsByTile(assembled), expected);
        first = false;
    }
}

TEST(TsdfTile, TileMeshesCutAtTheCoreAreTheWholeMesh) {
    const Scene scene = Scenes().front();
    TsdfVolume whole(scene.config);
    whole.Integrate(scene.scans);
    const std::vector<Tri> expected = Triangles(whole.ExtractIsoSurface().mesh);
    ASSERT_GT(expected.size(), 1000u);
    std::vector<Tri> joined;
    for (const auto& [tile, voxels] : VoxelsByTile(whole)) {
        const VoxelColumns core = Core(tile.first, tile.second);
        TsdfVolume part(scene.config, Grown(core, kTile));
        part.Integrate(scene.scans);
        const TriangleMesh cut =
            KeepTrianglesIn(part.ExtractIsoSurface().mesh, core, scene.config.voxel_size_m);
        for (const Tri& t : Triangles(cut)) joined.push_back(t);
    }
    std::sort(joined.begin(), joined.end());
    EXPECT_EQ(joined.size(), expected.size());
    EXPECT_EQ(joined, expected);
}

TEST(TsdfTile, PingsOverTheTileAloneAreNotEnough) {
    const Scene scene = Scenes().front();
    TsdfVolume whole(scene.config);
    whole.Integrate(scene.scans);
    const auto expected = VoxelsByTile(whole);
    const double s = scene.config.voxel_size_m;
    int differing = 0;
    for (const auto& [tile, voxels] : expected) {
        const VoxelColumns core = Core(tile.first, tile.second);
        std::vector<SonarScan> over;
        for (const SonarScan& scan : scene.scans) {
            const Eigen::Vector3d p = scan.T_world_sonar.translation() / s;
            if (p.x() >= core.x_min && p.x() <= core.x_max && p.y() >= core.y_min &&
                p.y() <= core.y_max) {
                over.push_back(scan);
            }
        }
        TsdfVolume part(scene.config, core);
        part.Integrate(over);
        const auto got = VoxelsByTile(part);
        const auto it = got.find(tile);
        if (it == got.end() || it->second != voxels) ++differing;
    }
    EXPECT_GT(differing, 0);
}

TEST(TsdfTile, RegionsOffTheAlignmentAreRefused) {
    EXPECT_TRUE(Core(-2, 3).Aligned());
    EXPECT_FALSE((VoxelColumns{1, 64, 0, 63}.Aligned()));
    EXPECT_FALSE((VoxelColumns{0, 62, 0, 63}.Aligned()));
    EXPECT_FALSE((VoxelColumns{0, -1, 0, 63}.Aligned()));
    EXPECT_DEATH(TsdfVolume(TsdfConfig{}, VoxelColumns{0, 10, 0, 63}), "kRegionAlignVoxels");
}

}  // namespace
}  // namespace pitmap::proc::fusion
