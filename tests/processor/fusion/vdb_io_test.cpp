// SPDX-License-Identifier: MIT
// .vdb export: written, read back with the same grids and active voxel counts; a volume read
// back gives the same field and mesh. Corrupted files (truncated, overwritten bytes, empty, no
// checksum trailer) are a clear error naming the file, never a crash.
#include "processor/fusion/vdb_io.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <vector>

#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>

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

std::vector<char> ReadBytes(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void WriteBytes(const std::string& path, const std::vector<char>& b) {
    std::ofstream(path, std::ios::binary | std::ios::trunc)
        .write(b.data(), static_cast<std::streamsize>(b.size()));
}

// A small fused volume written to `path`; returns its bytes.
std::vector<char> WriteSmallVolume(const std::string& path) {
    testing::SyntheticWorld world;
    testing::LineSurvey survey;
    survey.x0_m = -1.0;
    survey.x1_m = 1.0;
    TsdfConfig config;
    config.truncation_m = 0.5;
    TsdfVolume volume(config);
    volume.Integrate(testing::MakeScans(world, survey));
    EXPECT_GT(volume.Stats().active_voxels, 0);
    EXPECT_TRUE(WriteVdb(volume, path, {{"pitmap_origin", "40.4435 -7.7806 412.0"}}));
    return ReadBytes(path);
}

// Reads a damaged file both ways (volume and info): a failure naming the file, never a crash.
void ExpectCleanError(const std::string& path, const std::string& what) {
    const auto read = ReadVdb(path);
    ASSERT_FALSE(read) << what;
    EXPECT_NE(read.error().message.find(path), std::string::npos)
        << what << ": " << read.error().message;
    const auto info = ReadVdbInfo(path);
    ASSERT_FALSE(info) << what;
    EXPECT_NE(info.error().message.find(path), std::string::npos) << what;
}

TEST(VdbIo, WrittenFileCarriesAChecksumTrailerOpenVdbIgnores) {
    const std::string path = ::testing::TempDir() + "/pitmap_tsdf_trailer_test.vdb";
    WriteSmallVolume(path);
    // OpenVDB itself still reads the file (the trailer follows its last grid).
    openvdb::initialize();
    openvdb::io::File file(path);
    file.open();
    EXPECT_EQ(file.getGrids()->size(), 2u);
    file.close();
    ASSERT_TRUE(ReadVdb(path));
    std::filesystem::remove(path);
}

TEST(VdbIo, TruncatedFilesAreCleanErrors) {
    const std::string path = ::testing::TempDir() + "/pitmap_tsdf_truncated_test.vdb";
    const std::vector<char> good = WriteSmallVolume(path);
    ASSERT_GT(good.size(), 1000u);
    const std::size_t n = good.size();
    for (std::size_t keep : {std::size_t{0},
                             std::size_t{1},
                             std::size_t{8},
                             std::size_t{23},
                             std::size_t{24},
                             std::size_t{100},
                             std::size_t{500},
                             n / 4,
                             n / 2,
                             n - 100,
                             n - 25,
                             n - 24,
                             n - 1}) {
        WriteBytes(path, std::vector<char>(good.begin(), good.begin() + static_cast<long>(keep)));
        ExpectCleanError(path, "truncated to " + std::to_string(keep) + " bytes");
    }
    std::filesystem::remove(path);
}

// Case 5 of issue 14: 20 random bytes overwritten at random offsets, 20 seeds. Before the
// checksum most of these crashed inside OpenVDB's reader (SIGSEGV, SIGABRT) or in the volume's
// destructor.
TEST(VdbIo, OverwrittenBytesAreCleanErrorsOverTwentySeeds) {
    const std::string path = ::testing::TempDir() + "/pitmap_tsdf_overwritten_test.vdb";
    const std::vector<char> good = WriteSmallVolume(path);
    for (unsigned seed = 1; seed <= 20; ++seed) {
        std::mt19937 rng(seed);
        std::vector<char> bad = good;
        std::uniform_int_distribution<std::size_t> at(0, bad.size() - 1);
        bool changed = false;
        for (int k = 0; k < 20; ++k) {
            const std::size_t i = at(rng);
            const char c = static_cast<char>(rng() & 0xff);
            changed |= bad[i] != c;
            bad[i] = c;
        }
        ASSERT_TRUE(changed);
        WriteBytes(path, bad);
        ExpectCleanError(path, "seed " + std::to_string(seed));
    }
    // One flipped bit anywhere in the OpenVDB part, at a few places.
    for (std::size_t i : {std::size_t{0}, std::size_t{40}, good.size() / 3, good.size() - 30}) {
        std::vector<char> bad = good;
        bad[i] = static_cast<char>(bad[i] ^ 0x10);
        WriteBytes(path, bad);
        ExpectCleanError(path, "bit flip at " + std::to_string(i));
    }
    std::filesystem::remove(path);
}

TEST(VdbIo, EmptyGarbageAndTrailerlessFilesAreCleanErrors) {
    const std::string path = ::testing::TempDir() + "/pitmap_tsdf_garbage_test.vdb";
    WriteBytes(path, {});
    ExpectCleanError(path, "empty file");
    WriteBytes(path, std::vector<char>(4096, '\xff'));
    ExpectCleanError(path, "4 KiB of 0xff");
    // A plain OpenVDB file (another writer, or pitmap before the trailer): no checksum.
    const std::vector<char> good = WriteSmallVolume(path);
    WriteBytes(path, std::vector<char>(good.begin(), good.end() - 24));
    ExpectCleanError(path, "no trailer");
    EXPECT_NE(ReadVdb(path).error().message.find("checksum trailer"), std::string::npos);
    // A trailer whose length field is huge.
    std::vector<char> bad = good;
    bad[bad.size() - 10] = '\x7f';
    WriteBytes(path, bad);
    ExpectCleanError(path, "huge length in the trailer");
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
