// SPDX-License-Identifier: MIT
// .vdb export: written, read back with the same grids and active voxel counts; a volume read
// back gives the same field and mesh.
#include "processor/fusion/vdb_io.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "tests/processor/fusion/synthetic_scans.hpp"

namespace pitmap::proc::fusion {
namespace {

TEST(VdbIo, WrittenFileReadsBackWithTheSameActiveVoxelCount) {
    testing::SyntheticWorld world;
    testing::LineSurvey survey;
    survey.x0_m = -2.0;
    survey.x1_m = 2.0;
    TsdfConfig config;
    config.truncation_m = 0.5;
    TsdfVolume volume(config);
    volume.Integrate(testing::MakeScans(world, survey));
    const std::int64_t active = volume.Stats().active_voxels;
    ASSERT_GT(active, 0);
    const std::string path = ::testing::TempDir() + "/pitmap_tsdf_test.vdb";
    ASSERT_TRUE(WriteVdb(volume, path, {{"pitmap_origin", "40.4435 -7.7806 412.0"}}));
    const auto info = ReadVdbInfo(path);
    ASSERT_TRUE(info) << info.error().message;
    ASSERT_EQ(info->grids.size(), 2u);
    EXPECT_EQ(info->grids[0].name, "tsdf");
    EXPECT_EQ(info->grids[1].name, "weight");
    EXPECT_EQ(info->grids[0].active_voxels, active);
    EXPECT_EQ(info->grids[1].active_voxels, active);
    EXPECT_DOUBLE_EQ(info->grids[0].voxel_size_m, 0.10);
    bool has_origin = false;
    for (const auto& m : info->metadata) has_origin |= m == "pitmap_origin=40.4435 -7.7806 412.0";
    EXPECT_TRUE(has_origin);
    std::filesystem::remove(path);
}

TEST(VdbIo, EmptyVolumeWritesAValidFile) {
    TsdfVolume volume(TsdfConfig{});
    const std::string path = ::testing::TempDir() + "/pitmap_tsdf_empty_test.vdb";
    ASSERT_TRUE(WriteVdb(volume, path));
    const auto info = ReadVdbInfo(path);
    ASSERT_TRUE(info) << info.error().message;
    ASSERT_EQ(info->grids.size(), 2u);
    EXPECT_EQ(info->grids[0].active_voxels, 0);
    std::filesystem::remove(path);
}

TEST(VdbIo, ReadVdbRoundTripGivesTheSameFieldAndMesh) {
    testing::SyntheticWorld world;
    testing::LineSurvey survey;
    survey.x0_m = -2.0;
    survey.x1_m = 2.0;
    survey.noise_sigma_m = 0.02;
    TsdfConfig config;
    config.voxel_size_m = 0.08;
    config.truncation_m = 0.5;
    TsdfVolume volume(config);
    volume.Integrate(testing::MakeScans(world, survey));
    const std::string path = ::testing::TempDir() + "/pitmap_tsdf_roundtrip_test.vdb";
    ASSERT_TRUE(WriteVdb(volume, path));
    // Grid parameters come from the file, the rest from the config given.
    TsdfConfig other;
    other.max_weight = 7.0f;
    auto read = ReadVdb(path, other);
    ASSERT_TRUE(read) << read.error().message;
    TsdfVolume& back = read.value();
    EXPECT_DOUBLE_EQ(back.config().voxel_size_m, 0.08);
    EXPECT_DOUBLE_EQ(back.config().truncation_m, 0.5);
    EXPECT_FLOAT_EQ(back.config().max_weight, 7.0f);
    EXPECT_EQ(back.Stats().active_voxels, volume.Stats().active_voxels);
    EXPECT_FLOAT_EQ(back.Stats().max_weight, volume.Stats().max_weight);
    for (double x = -1.5; x <= 1.5; x += 0.25) {
        for (double z = -10.4; z <= -9.6; z += 0.08) {
            const Eigen::Vector3d p(x, 0.7, z);
            EXPECT_FLOAT_EQ(back.DistanceAt(p), volume.DistanceAt(p));
            EXPECT_FLOAT_EQ(back.WeightAt(p), volume.WeightAt(p));
        }
    }
    const TriangleMesh a = volume.ExtractIsoSurface().mesh;
    const TriangleMesh b = back.ExtractIsoSurface().mesh;
    ASSERT_GT(a.vertices.size(), 1000u);
    EXPECT_EQ(a.vertices.size(), b.vertices.size());
    EXPECT_EQ(a.triangles.size(), b.triangles.size());
    // The read volume is a working volume: filtering and further integration act on it.
    const WeightFilterResult fr = back.FilterByWeight({.min_weight = 2.0f});
    EXPECT_EQ(fr.voxels_before, volume.Stats().active_voxels);
    back.Integrate(testing::MakeScans(world, survey));
    EXPECT_LE(back.Stats().max_weight, 7.0f);
    std::filesystem::remove(path);
}

TEST(VdbIo, ReadVdbOfAnEmptyVolumeIsEmpty) {
    TsdfVolume volume(TsdfConfig{});
    const std::string path = ::testing::TempDir() + "/pitmap_tsdf_empty_read_test.vdb";
    ASSERT_TRUE(WriteVdb(volume, path));
    auto read = ReadVdb(path);
    ASSERT_TRUE(read) << read.error().message;
    EXPECT_EQ(read->Stats().active_voxels, 0);
    EXPECT_DOUBLE_EQ(read->config().truncation_m, 1.5);
    EXPECT_TRUE(read->ExtractIsoSurface().mesh.vertices.empty());
    std::filesystem::remove(path);
}

TEST(VdbIo, ReadVdbRejectsMissingAndCorruptFiles) {
    const auto missing = ReadVdb(::testing::TempDir() + "/no/such/file.vdb");
    ASSERT_FALSE(missing);
    EXPECT_NE(missing.error().message.find("cannot read VDB"), std::string::npos);
    const std::string path = ::testing::TempDir() + "/pitmap_tsdf_corrupt_test.vdb";
    std::ofstream(path, std::ios::trunc) << "not a vdb file";
    EXPECT_FALSE(ReadVdb(path));
    std::filesystem::remove(path);
}

TEST(VdbIo, UnwritablePathIsAnError) {
    TsdfVolume volume(TsdfConfig{});
    const auto s = WriteVdb(volume, ::testing::TempDir() + "/no/such/dir/x.vdb");
    EXPECT_FALSE(s);
    EXPECT_FALSE(ReadVdbInfo(::testing::TempDir() + "/no/such/file.vdb"));
}

}  // namespace
}  // namespace pitmap::proc::fusion
