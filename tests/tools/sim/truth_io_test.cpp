// SPDX-License-Identifier: MIT
#include "tools/sim/truth_io.hpp"

#include <gtest/gtest.h>

#include <unistd.h>
#include <filesystem>
#include <fstream>

#include "common/frames.hpp"

namespace pitmap::sim {
namespace {

namespace fs = std::filesystem;

class TruthIo : public ::testing::Test {
protected:
    void SetUp() override {
        dir_ = fs::path(::testing::TempDir()) / ("pitmap_truth_" + std::to_string(::getpid()));
        fs::create_directories(dir_);
    }
    void TearDown() override { fs::remove_all(dir_); }
    fs::path dir_;
};

Truth SmallTruth() {
    Truth t;
    t.origin = {40.0, -7.0, 400.0};
    t.terrain.x0_m = -2;
    t.terrain.y0_m = -1;
    t.terrain.resolution_m = 0.5;
    t.terrain.nx = 9;
    t.terrain.ny = 5;
    for (int i = 0; i < 45; ++i)
        t.terrain.height_m.push_back(-10.0f - 0.125f * static_cast<float>(i));
    for (int k = 0; k < 4; ++k) {
        TruthPose p;
        p.gps_time_s = 1.4e9 + 0.1 * k;
        p.T_world_vehicle = MakePose(frames::RotationWorldFromRpy(0.01 * k, -0.02, 1.0 + 0.1 * k),
                                     Eigen::Vector3d(k, 2.0 * k, 0.01));
        t.trajectory.push_back(p);
    }
    t.boresight = {0.5, -0.25, 1.0, {0.8, 0.0, 0.25}};
    return t;
}

TEST_F(TruthIo, RoundTrip) {
    const Truth t = SmallTruth();
    ASSERT_TRUE(WriteTruth(dir_.string(), *BuiltinScenario("demo"), t).ok());
    auto back = ReadTruth(dir_.string());
    ASSERT_TRUE(back.ok()) << back.error().message;
    EXPECT_EQ(back->terrain.height_m, t.terrain.height_m);
    EXPECT_EQ(back->terrain.nx, 9);
    EXPECT_DOUBLE_EQ(back->origin.latitude_deg, 40.0);
    ASSERT_EQ(back->trajectory.size(), 4u);
    for (std::size_t k = 0; k < 4; ++k) {
        EXPECT_NEAR(back->trajectory[k].gps_time_s, t.trajectory[k].gps_time_s, 1e-6);
        EXPECT_TRUE(
            back->trajectory[k].T_world_vehicle.isApprox(t.trajectory[k].T_world_vehicle, 1e-4));
    }
    EXPECT_DOUBLE_EQ(back->boresight.yaw_deg, 1.0);
    // A world built from the read grid answers like the original.
    const PitWorld w(back->terrain);
    EXPECT_NEAR(w.Height(-2.0, -1.0), -10.0, 1e-6);
}

TEST_F(TruthIo, InterpolationAndItsBounds) {
    const Truth t = SmallTruth();
    auto mid = InterpolateTruth(t.trajectory, 1.4e9 + 0.05);
    ASSERT_TRUE(mid.ok());
    EXPECT_TRUE(mid->translation().isApprox(Eigen::Vector3d(0.5, 1.0, 0.01), 1e-6));
    EXPECT_FALSE(InterpolateTruth(t.trajectory, 1.4e9 - 1).ok());
    EXPECT_FALSE(InterpolateTruth(t.trajectory, 1.4e9 + 1).ok());
}

TEST_F(TruthIo, DamagedFilesAreNamedErrors) {
    ASSERT_TRUE(WriteTruth(dir_.string(), *BuiltinScenario("demo"), SmallTruth()).ok());
    fs::resize_file(dir_ / "terrain.f32", 17);
    auto r = ReadTruth(dir_.string());
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.error().message.find("terrain.f32"), std::string::npos);
    ASSERT_TRUE(WriteTruth(dir_.string(), *BuiltinScenario("demo"), SmallTruth()).ok());
    std::ofstream(dir_ / "trajectory.csv", std::ios::app) << "1,2,three\n";
    r = ReadTruth(dir_.string());
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.error().message.find("trajectory.csv:6"), std::string::npos) << r.error().message;
    EXPECT_FALSE(ReadTruth((dir_ / "missing").string()).ok());
}

}  // namespace
}  // namespace pitmap::sim
