// SPDX-License-Identifier: MIT
#include "tools/sim/truth_io.hpp"

#include <gtest/gtest.h>

#include <unistd.h>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "common/frames.hpp"
#include "tools/sim/sonar_model.hpp"

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

TEST_F(TruthIo, SonarClockIsStatedAndReadBack) {
    ScenarioConfig sc = *BuiltinScenario("quarry");
    sc.sonar.topside_clock_drift_ppm = 100.0;
    const std::int64_t start_gps = 1'465'549'218'000'000;
    Truth t = SmallTruth();
    t.sonar_clock = MakeSonarClockTruth(sc, start_gps, 210.0);
    const SonarClockTruth& c = *t.sonar_clock;
    EXPECT_DOUBLE_EQ(c.offset_s, 2.350);
    EXPECT_EQ(c.gps_minus_utc_s, 18);
    EXPECT_DOUBLE_EQ(c.survey_start_gps_s, 1'465'549'218.0);
    // Interrogations at k / 10 - 2 ms for k = 0..2099.
    EXPECT_NEAR(c.first_ping_offset_s, 2.350 - 100e-6 * 0.002, 1e-12);
    EXPECT_NEAR(c.last_ping_offset_s, 2.350 + 100e-6 * (209.9 - 0.002), 1e-12);
    EXPECT_NEAR(c.ingest_sonar_clock_offset_s, c.first_ping_offset_s - 0.002, 1e-12);
    EXPECT_TRUE(c.nmea_position && c.nmea_heading && c.internal_attitude_sensor);
    ASSERT_TRUE(WriteTruth(dir_.string(), sc, t).ok());
    std::ifstream in(dir_ / "sonar_clock.json");
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_NE(text.find("sonar header time - UTC"), std::string::npos);
    EXPECT_NE(text.find("header time (read as UTC) + (GPS - UTC) - offset(t)"), std::string::npos);
    auto back = ReadTruth(dir_.string());
    ASSERT_TRUE(back.ok()) << back.error().message;
    ASSERT_TRUE(back->sonar_clock.has_value());
    EXPECT_DOUBLE_EQ(back->sonar_clock->offset_s, 2.350);
    EXPECT_DOUBLE_EQ(back->sonar_clock->drift_ppm, 100.0);
    EXPECT_DOUBLE_EQ(back->sonar_clock->last_ping_offset_s, c.last_ping_offset_s);
    EXPECT_DOUBLE_EQ(back->sonar_clock->nmea_latency_s, 0.15);
    // Without the file (older truth folders) there is no clock truth, and no error.
    fs::remove(dir_ / "sonar_clock.json");
    back = ReadTruth(dir_.string());
    ASSERT_TRUE(back.ok());
    EXPECT_FALSE(back->sonar_clock.has_value());
}

// The seabed backscatter and the amplitude model's parameters: written, read back; a truth
// without them reads as none; a short data file is a named error.
TEST_F(TruthIo, BackscatterIsStatedAndReadBack) {
    Truth t = SmallTruth();
    ASSERT_TRUE(WriteTruth(dir_.string(), *BuiltinScenario("demo"), t).ok());
    auto none = ReadTruth(dir_.string());
    ASSERT_TRUE(none.ok()) << none.error().message;
    EXPECT_TRUE(none->backscatter_db.empty());
    EXPECT_FALSE(fs::exists(dir_ / "backscatter.json"));

    for (int i = 0; i < 45; ++i) t.backscatter_db.push_back(i % 2 ? -14.0f : -32.0f);
    t.backscatter.source_level_db = 104.5;
    t.backscatter.absorption_db_per_m = 0.03;
    t.backscatter.patch_levels_db = {-14.0, -32.0};
    ASSERT_TRUE(WriteTruth(dir_.string(), *BuiltinScenario("demo"), t).ok());
    auto back = ReadTruth(dir_.string());
    ASSERT_TRUE(back.ok()) << back.error().message;
    EXPECT_EQ(back->backscatter_db, t.backscatter_db);
    EXPECT_EQ(back->backscatter.source_level_db, 104.5);
    EXPECT_EQ(back->backscatter.absorption_db_per_m, 0.03);
    EXPECT_EQ(back->backscatter.patch_levels_db, t.backscatter.patch_levels_db);
    EXPECT_EQ(back->backscatter.spreading_db_per_decade, 40.0);

    fs::resize_file(dir_ / "backscatter.f32", 40);
    auto bad = ReadTruth(dir_.string());
    ASSERT_FALSE(bad.ok());
    EXPECT_NE(bad.error().message.find("backscatter.f32"), std::string::npos);
}

// The truth per beam of the echo artifacts: runs merged per ping and kind, written, read back
// and looked up; the counts are in scenario.json; a truncated run list is a named error.
TEST_F(TruthIo, EchoArtifactsAreStatedPerBeamAndReadBack) {
    Truth t = SmallTruth();
    const PitWorld world(t.terrain);
    ArtifactTruth a;
    a.config = *EchoArtifactsAt("typical");
    a.ping_rate_hz = 10;
    a.first_ping_gps_s = 1.4e9;
    for (std::int64_t k = 0; k < 3; ++k) {
        SimPing p;
        p.ping_number = k;
        p.range_counts.assign(6, 100);
        p.true_hit_world.assign(6, Eigen::Vector3d(0, 0, -10.5));
        p.artifact.assign(6, EchoArtifactKind::kNone);
        if (k == 1) {
            p.artifact[1] = p.artifact[2] = EchoArtifactKind::kMidWater;
            p.artifact[3] = EchoArtifactKind::kMultipath;
            p.artifact[5] = EchoArtifactKind::kDropout;
            p.range_counts[5] = 0;
        }
        if (k == 2) p.range_counts[0] = 0;  // no detection: not a good sounding
        a.Add(p, world);
    }
    ASSERT_EQ(a.runs.size(), 3u);
    EXPECT_EQ(a.runs[0].num_beams, 2);
    EXPECT_EQ(a.artifact_soundings(), 3);
    EXPECT_EQ(a.good_soundings, 6 + 2 + 5);
    EXPECT_EQ(a.good_by_slope[0] + a.good_by_slope[1] + a.good_by_slope[2], 13);
    t.artifacts = a;
    ASSERT_TRUE(WriteTruth(dir_.string(), *BuiltinScenario("demo"), t).ok());
    auto back = ReadTruth(dir_.string());
    ASSERT_TRUE(back.ok()) << back.error().message;
    ASSERT_TRUE(back->artifacts.has_value());
    const ArtifactTruth& b = *back->artifacts;
    EXPECT_EQ(b.runs.size(), 3u);
    EXPECT_EQ(b.pings, 3);
    EXPECT_EQ(b.beams_per_ping, 6);
    EXPECT_EQ(b.good_soundings, 13);
    EXPECT_DOUBLE_EQ(b.first_ping_gps_s, 1.4e9);
    EXPECT_EQ(b.KindOf(1, 0), EchoArtifactKind::kNone);
    EXPECT_EQ(b.KindOf(1, 1), EchoArtifactKind::kMidWater);
    EXPECT_EQ(b.KindOf(1, 2), EchoArtifactKind::kMidWater);
    EXPECT_EQ(b.KindOf(1, 3), EchoArtifactKind::kMultipath);
    EXPECT_EQ(b.KindOf(1, 4), EchoArtifactKind::kNone);
    EXPECT_EQ(b.KindOf(1, 5), EchoArtifactKind::kDropout);
    EXPECT_EQ(b.KindOf(2, 1), EchoArtifactKind::kNone);
    EXPECT_EQ(b.KindOf(0, 1), EchoArtifactKind::kNone);
    std::ifstream in(dir_ / "scenario.json");
    const std::string sc((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_NE(sc.find("\"artifact_soundings\": 3"), std::string::npos) << sc;

    fs::resize_file(dir_ / "artifacts.bin", 20);
    auto bad = ReadTruth(dir_.string());
    ASSERT_FALSE(bad.ok());
    EXPECT_NE(bad.error().message.find("artifacts.bin"), std::string::npos);
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
