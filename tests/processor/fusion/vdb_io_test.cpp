// SPDX-License-Identifier: MIT
// .vdb export: written, read back with the same grids and active voxel counts.
#include "processor/fusion/vdb_io.hpp"

#include <gtest/gtest.h>

#include <filesystem>

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

TEST(VdbIo, UnwritablePathIsAnError) {
    TsdfVolume volume(TsdfConfig{});
    const auto s = WriteVdb(volume, ::testing::TempDir() + "/no/such/dir/x.vdb");
    EXPECT_FALSE(s);
    EXPECT_FALSE(ReadVdbInfo(::testing::TempDir() + "/no/such/file.vdb"));
}

}  // namespace
}  // namespace pitmap::proc::fusion
