// SPDX-License-Identifier: MIT
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <random>

#include "common/frames.hpp"
#include "tools/eval/scores.hpp"

namespace pitmap::eval {
namespace {

namespace fs = std::filesystem;

class Eval : public ::testing::Test {
protected:
    void SetUp() override {
        dir_ = fs::path(::testing::TempDir()) / ("pitmap_eval_" + std::to_string(::getpid()));
        fs::remove_all(dir_);
        fs::create_directories(dir_ / "truth");
        fs::create_directories(dir_ / "products");
    }
    void TearDown() override { fs::remove_all(dir_); }
    fs::path dir_;
};

// A flat floor at z = -10 and a straight true track along x at 1 m/s.
sim::Truth FlatTruth() {
    sim::Truth t;
    t.origin = {40.4435, -7.7806, 412.0};
    t.terrain.x0_m = -50;
    t.terrain.y0_m = -50;
    t.terrain.resolution_m = 1.0;
    t.terrain.nx = t.terrain.ny = 101;
    t.terrain.height_m.assign(101 * 101, -10.0f);
    for (int k = 0; k <= 100; ++k) {
        t.trajectory.push_back(
            {1.4e9 + k, MakePose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(k - 50.0, 0, 0))});
    }
    t.boresight = {0.5, 0.0, 1.0, {0.8, 0.0, 0.25}};
    return t;
}

void WritePlyAscii(const fs::path& p,
                   const std::vector<Eigen::Vector3d>& v,
                   const std::string& comment,
                   const std::vector<std::array<int, 4>>& quads = {}) {
    std::ofstream out(p);
    out << "ply\nformat ascii 1.0\n";
    if (!comment.empty()) out << "comment " << comment << "\n";
    out << "element vertex " << v.size()
        << "\nproperty double x\nproperty double y\nproperty double z\n"
        << "property uchar red\n";
    out << "element face " << quads.size()
        << "\nproperty list uchar int vertex_indices\nend_header\n";
    for (const auto& x : v) out << x.x() << " " << x.y() << " " << x.z() << " 7\n";
    for (const auto& q : quads)
        out << "4 " << q[0] << " " << q[1] << " " << q[2] << " " << q[3] << "\n";
}

TEST(Frames, ProductToTruthIsExactForNearbyOrigins) {
    const Geodetic truth_origin{40.4435, -7.7806, 412.0};
    const Geodetic prod_origin{40.4440, -7.7800, 410.0};
    const Pose T = ProductToTruthFrame(prod_origin, truth_origin);
    const LocalTangentFrame prod(prod_origin), truth(truth_origin);
    for (const Eigen::Vector3d& p : {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(60, -45, -27)}) {
        EXPECT_LT((T * p - truth.ToEnu(prod.FromEnu(p))).norm(), 1e-6);
    }
    EXPECT_TRUE(ProductToTruthFrame(truth_origin, truth_origin).isApprox(Pose::Identity(), 1e-9));
}

TEST(Scores, DistanceStatistics) {
    const DistanceStats s = SummariseDistances({-1, 1, -1, 1});
    EXPECT_DOUBLE_EQ(s.rms_m, 1.0);
    EXPECT_DOUBLE_EQ(s.bias_m, 0.0);
    EXPECT_DOUBLE_EQ(s.p95_m, 1.0);
    std::vector<double> d(100);
    for (int i = 0; i < 100; ++i) d[static_cast<std::size_t>(i)] = i + 1;  // 1..100
    EXPECT_DOUBLE_EQ(SummariseDistances(d).p95_m, 95.0);
    EXPECT_EQ(SummariseDistances({}).count, 0u);
}

TEST(Scores, BoresightAngle) {
    EXPECT_NEAR(BoresightErrorDeg(0.5, 0, 1.0, 0.5, 0, 1.0), 0.0, 1e-9);
    EXPECT_NEAR(BoresightErrorDeg(0.5, 0, 2.0, 0.5, 0, 1.0), 1.0, 1e-6);
    EXPECT_NEAR(BoresightErrorDeg(0, 0, 0, 0.3, 0.4, 0), 0.5, 1e-3);
}

TEST_F(Eval, TruthScoresZeroAndAKnownShiftScoresThatShift) {
    const sim::Truth truth = FlatTruth();
    ASSERT_TRUE(
        sim::WriteTruth((dir_ / "truth").string(), *sim::BuiltinScenario("demo"), truth).ok());
    const double shift = 0.25;  // metres up
    for (const double dz : {0.0, shift}) {
        // Trajectory: the truth, shifted.
        {
            std::ofstream csv(dir_ / "products" / "trajectory.csv");
            csv << "gps_time_s,x_m,y_m,z_m,roll_deg,pitch_deg,yaw_deg\n";
            csv.precision(12);
            for (const auto& p : truth.trajectory) {
                const Eigen::Vector3d t = p.T_world_vehicle.translation();
                csv << p.gps_time_s << "," << t.x() << "," << t.y() << "," << t.z() + dz
                    << ",0,0,0\n";
            }
        }
        // Points on the floor, shifted; a 2 x 2 quad mesh likewise.
        std::vector<Eigen::Vector3d> pts;
        for (int i = 0; i < 50; ++i) pts.emplace_back(i - 25.0, 0.5 * i - 12, -10.0 + dz);
        WritePlyAscii(dir_ / "products" / "points.ply", pts, "pitmap_origin 40.4435 -7.7806 412.0");
        WritePlyAscii(dir_ / "products" / "mesh.ply",
                      {{-5, -5, -10 + dz}, {5, -5, -10 + dz}, {5, 5, -10 + dz}, {-5, 5, -10 + dz}},
                      "",
                      {{0, 1, 2, 3}});
        std::ofstream(dir_ / "products" / "boresight.json")
            << "{\"roll_deg\": 0.5, \"pitch_deg\": 0.0, \"yaw_deg\": " << (1.0 + dz) << "}\n";
        const fs::path json_path = dir_ / "scores.json";
        const std::string cmd = std::string(PITMAP_BIN_DIR) + "/pitmap-eval --truth '" +
                                (dir_ / "truth").string() + "' --products '" +
                                (dir_ / "products").string() + "' --json '" + json_path.string() +
                                "' > /dev/null";
        ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
        std::ifstream in(json_path);
        const auto j = nlohmann::json::parse(in);
        EXPECT_NEAR(j.at("trajectory_ate_rmse_m").get<double>(), dz, 1e-6);
        EXPECT_NEAR(j.at("points_rms_m").get<double>(), dz, 1e-4);
        EXPECT_NEAR(j.at("points_p95_m").get<double>(), dz, 1e-4);
        EXPECT_NEAR(j.at("mesh_mean_abs_m").get<double>(), dz, 1e-4);
        EXPECT_NEAR(j.at("boresight_error_deg").get<double>(), dz, 1e-6);  // yaw off by dz degrees
    }
}

TEST(Scores, KeepAcceptedKeepsStatusZeroWithTheirBeamsAndProperties) {
    formats::ply::Mesh m;
    m.vertices = {Eigen::Vector3d(0, 0, 0),
                  Eigen::Vector3d(1, 0, 0),
                  Eigen::Vector3d(2, 0, 0),
                  Eigen::Vector3d(3, 0, 0)};
    m.vertex_beam = {10, 11, 12, 13};
    m.vertex_properties = {
        {100, 101, 102, 103}, {0, 6, 0, std::numeric_limits<double>::quiet_NaN()}, {7, 8, 9, 10}};
    EXPECT_EQ(KeepAccepted(m, 1), 2u);
    ASSERT_EQ(m.vertices.size(), 2u);
    EXPECT_EQ(m.vertices[1].x(), 2.0);
    EXPECT_EQ(m.vertex_beam, (std::vector<int>{10, 12}));
    ASSERT_EQ(m.vertex_properties.size(), 2u) << "the status property is removed";
    EXPECT_EQ(m.vertex_properties[0], (std::vector<double>{100, 102}));
    EXPECT_EQ(m.vertex_properties[1], (std::vector<double>{7, 9}));
    EXPECT_EQ(KeepAccepted(m, 5), 0u) << "no such property: nothing dropped";
    EXPECT_EQ(m.vertices.size(), 2u);
}

// Issue 35: points.ply holds the rejected soundings too (status != 0). Only the accepted count
// as "in points": an artifact rejected by the cleaning scores as rejected, a good sounding
// rejected by mistake as a good one lost, and the rejected soundings far off the floor do not
// enter points_rms_m.
TEST_F(Eval, RejectedSoundingsInPointsPlyAreNotInPoints) {
    sim::Truth truth = FlatTruth();
    sim::ArtifactTruth a;
    a.beams_per_ping = 10;
    a.pings = 10;
    a.first_ping_gps_s = 1.4e9;
    a.ping_rate_hz = 1;
    // Ping 2, beams 3 and 4: mid-water (a fish); ping 5, beam 0: multipath.
    a.runs = {{2, 3, 2, sim::EchoArtifactKind::kMidWater},
              {5, 0, 1, sim::EchoArtifactKind::kMultipath}};
    a.beams_by_kind[static_cast<int>(sim::EchoArtifactKind::kMidWater)] = 2;
    a.beams_by_kind[static_cast<int>(sim::EchoArtifactKind::kMultipath)] = 1;
    a.good_soundings = 97;
    a.good_by_slope[0] = 97;
    truth.artifacts = a;
    ASSERT_TRUE(
        sim::WriteTruth((dir_ / "truth").string(), *sim::BuiltinScenario("demo"), truth).ok());
    {
        std::ofstream out(dir_ / "products" / "points.ply");
        out << "ply\nformat ascii 1.0\ncomment pitmap_origin 40.4435 -7.7806 412.0\n"
            << "element vertex 100\nproperty float x\nproperty float y\nproperty float z\n"
            << "property double gps_time_s\nproperty ushort beam\nproperty uchar status\n"
            << "end_header\n";
        out.precision(12);
        for (int k = 0; k < 10; ++k) {
            for (int b = 0; b < 10; ++b) {
                const bool fish = k == 2 && (b == 3 || b == 4);
                const bool multipath = k == 5 && b == 0;
                const bool lost = k == 7 && b == 9;  // a good sounding rejected (a spike)
                // The fish are rejected (free space), the multipath is accepted.
                const int status = fish ? 6 : lost ? 3 : 0;
                const double z = fish ? -5.0 : multipath ? -12.0 : lost ? -10.0 : -10.0;
                out << b - 5.0 << " " << k - 5.0 << " " << z << " " << 1.4e9 + k << " " << b << " "
                    << status << "\n";
            }
        }
    }
    const fs::path json_path = dir_ / "scores.json";
    const std::string cmd = std::string(PITMAP_BIN_DIR) + "/pitmap-eval --truth '" +
                            (dir_ / "truth").string() + "' --products '" +
                            (dir_ / "products").string() + "' --json '" + json_path.string() +
                            "' > /dev/null";
    ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
    std::ifstream in(json_path);
    const auto j = nlohmann::json::parse(in);
    EXPECT_EQ(j.at("points_accepted").get<int>(), 97);
    EXPECT_EQ(j.at("points_rejected").get<int>(), 3);
    EXPECT_EQ(j.at("points_scored").get<int>(), 97);
    EXPECT_EQ(j.at("artifact_in_points_mid_water").get<int>(), 0);
    EXPECT_EQ(j.at("artifact_in_points_multipath").get<int>(), 1);
    EXPECT_EQ(j.at("artifact_in_points").get<int>(), 1);
    EXPECT_DOUBLE_EQ(j.at("artifact_rejected_share_mid_water").get<double>(), 1.0);
    EXPECT_NEAR(j.at("artifact_rejected_share").get<double>(), 2.0 / 3.0, 1e-12);
    EXPECT_EQ(j.at("good_in_points").get<int>(), 96);
    EXPECT_NEAR(j.at("good_rejected_share").get<double>(), 1.0 / 97.0, 1e-12);
    EXPECT_NEAR(j.at("points_rms_m_good").get<double>(), 0.0, 1e-4);
    // The one accepted multipath point, 2 m deep of the floor, among 97.
    EXPECT_NEAR(j.at("points_rms_m").get<double>(), std::sqrt(4.0 / 97.0), 1e-4);
}

// Per-window ATE: "before" 0.1 m off in the first 50 s, "after" 0.03 m off in 50-75 s only;
// windows of 25 s from the first true pose (101 poses over 100 s: the last window holds one).
TEST(Scores, TrajectoryWindowsScoreEachWindowOnItsOwn) {
    const sim::Truth truth = FlatTruth();
    std::vector<ProductPose> before, after;
    for (const auto& p : truth.trajectory) {
        const double t = p.gps_time_s - truth.trajectory.front().gps_time_s;
        const Eigen::Vector3d x = p.T_world_vehicle.translation();
        before.push_back({p.gps_time_s, x + Eigen::Vector3d(0, t < 50 ? 0.1 : 0.0, 0)});
        after.push_back({p.gps_time_s, x + Eigen::Vector3d(0, 0, t >= 50 && t < 75 ? 0.03 : 0.0)});
    }
    const Pose I = Pose::Identity();
    const auto w = ScoreTrajectoryWindows(after, before, I, truth.trajectory, 25.0);
    ASSERT_EQ(w.size(), 4u);
    EXPECT_DOUBLE_EQ(w[0].t0_s, 0.0);
    EXPECT_DOUBLE_EQ(w[3].t1_s, 100.0);
    EXPECT_EQ(w[0].poses, 25u);
    EXPECT_NEAR(w[0].before_m, 0.1, 1e-9);
    EXPECT_NEAR(w[0].after_m, 0.0, 1e-9);
    EXPECT_NEAR(w[2].before_m, 0.0, 1e-9);
    EXPECT_NEAR(w[2].after_m, 0.03, 1e-9);
    EXPECT_NEAR(w[3].after_m, 0.0, 1e-9);
    // A window without poses on one side is left out; no window without a truth.
    after.erase(after.begin() + 25, after.begin() + 50);
    EXPECT_EQ(ScoreTrajectoryWindows(after, before, I, truth.trajectory, 25.0).size(), 3u);
    EXPECT_TRUE(ScoreTrajectoryWindows(after, before, I, {}, 25.0).empty());
    EXPECT_TRUE(ScoreTrajectoryWindows(after, before, I, truth.trajectory, 0.0).empty());
}

// The stated 95 % radius 2.4477 sqrt((sE^2 + sN^2) / 2): errors just inside and just outside
// it, the vertical against 1.96 sU, the outage class by the INS's sigma; and the CSV read back.
TEST(Scores, UncertaintyCountsErrorsWithinTheStatedRadius) {
    const sim::Truth truth = FlatTruth();
    std::vector<StatedPose> poses;
    const double r95 = 2.4477 * 0.1;  // sE = sN = 0.1 m
    for (std::size_t k = 0; k < truth.trajectory.size(); ++k) {
        const auto& p = truth.trajectory[k];
        StatedPose s;
        s.gps_time_s = p.gps_time_s;
        const bool inside = k % 4 != 0;  // 3 of 4 inside
        s.position = p.T_world_vehicle.translation() +
                     Eigen::Vector3d(0.6 * r95, (inside ? 0.79 : 0.81) * r95, 0.1);
        s.initial = p.T_world_vehicle.translation() + Eigen::Vector3d(2.0, 0, 0);
        s.sigma_enu_m = {0.1, 0.1, k % 2 == 0 ? 0.06 : 0.04};  // 1.96 * 0.06 > 0.1 > 1.96 * 0.04
        const bool outage = k < 20;
        s.ins_sigma_enu_m = Eigen::Vector3d::Constant(outage ? 1.0 : 0.1);
        poses.push_back(s);
    }
    const UncertaintyScore u = ScoreUncertainty(poses, Pose::Identity(), truth.trajectory, 0.5);
    ASSERT_EQ(u.after_all.poses, truth.trajectory.size());
    EXPECT_NEAR(u.after_all.share_within_h95, 0.75, 0.02);
    EXPECT_NEAR(u.after_all.share_within_v95, 0.5, 0.02);
    EXPECT_NEAR(u.after_all.median_radius_h95_m, r95, 1e-9);
    EXPECT_EQ(u.after_outage.poses, 20u);
    // Before: 2 m off with the INS's sigma: within 2.45 m in the outage only.
    EXPECT_DOUBLE_EQ(u.before_outage.share_within_h95, 1.0);
    EXPECT_NEAR(u.before_all.share_within_h95, 20.0 / static_cast<double>(poses.size()), 1e-9);
    EXPECT_NEAR(u.before_all.median_error_h_m, 2.0, 1e-9);

    const fs::path path =
        fs::temp_directory_path() / ("pitmap_eval_sigma_" + std::to_string(::getpid()) + ".csv");
    {
        std::ofstream f(path);
        f << "gps_time_s,x_m,y_m,z_m,x0_m,y0_m,z0_m,sigma_east_m,sigma_north_m,sigma_up_m,"
             "sigma_roll_deg,sigma_pitch_deg,sigma_yaw_deg,ins_sigma_east_m,ins_sigma_north_m,"
             "ins_sigma_up_m,slam_posterior\n"
          << "100.5,1,2,3,4,5,6,0.1,0.2,0.3,0.01,0.02,0.03,1,2,3,1\n";
    }
    const auto read = ReadTrajectorySigmaCsv(path.string());
    ASSERT_TRUE(read.ok()) << read.error().message;
    ASSERT_EQ(read->size(), 1u);
    EXPECT_EQ((*read)[0].initial, Eigen::Vector3d(4, 5, 6));
    EXPECT_EQ((*read)[0].sigma_enu_m, Eigen::Vector3d(0.1, 0.2, 0.3));
    EXPECT_EQ((*read)[0].ins_sigma_enu_m, Eigen::Vector3d(1, 2, 3));
    EXPECT_TRUE((*read)[0].slam_posterior);
    {
        std::ofstream f(path, std::ios::app);
        f << "101,1,2,3\n";
    }
    const auto bad = ReadTrajectorySigmaCsv(path.string());
    ASSERT_FALSE(bad.ok());
    EXPECT_NE(bad.error().message.find("row 3"), std::string::npos) << bad.error().message;
    fs::remove(path);
}

TEST(Scores, MeshCompletenessCountsCoveredCellsNearTheMesh) {
    sim::Truth truth = FlatTruth();                         // 1 m cells, floor at z = -10
    EXPECT_FALSE(MeshCompleteness({}, truth).has_value());  // no coverage mask
    truth.coverage.assign(truth.terrain.height_m.size(), 0);
    int covered = 0;
    for (int iy = 0; iy < truth.terrain.ny; ++iy) {
        for (int ix = 0; ix < truth.terrain.nx; ++ix) {
            const double x = truth.terrain.x0_m + ix, y = truth.terrain.y0_m + iy;
            if (std::abs(x) <= 10 && std::abs(y) <= 2) {
                truth.coverage[static_cast<std::size_t>(iy * truth.terrain.nx + ix)] = 1;
                ++covered;
            }
        }
    }
    ASSERT_EQ(covered, 21 * 5);
    // A dense mesh sample grid over x in [-10, 0]: covers x = -10..0 (11 columns of cells).
    std::vector<Eigen::Vector3d> samples;
    for (double x = -10; x <= 0.0001; x += 0.1)
        for (double y = -2.5; y <= 2.5001; y += 0.1) samples.emplace_back(x, y, -10.05);
    auto c = MeshCompleteness(samples, truth);
    ASSERT_TRUE(c.has_value());
    EXPECT_NEAR(*c, 55.0 / 105.0, 1e-12);
    // By slope class: a flat floor is all in the first class, none in the steep ones.
    EXPECT_NEAR(*MeshCompleteness(samples, truth, 0.2, 0, 20), 55.0 / 105.0, 1e-12);
    EXPECT_FALSE(MeshCompleteness(samples, truth, 0.2, 45, 91).has_value());
    EXPECT_NEAR(SlopeDeg(sim::PitWorld(truth.terrain), 1.0, 1.0), 0.0, 1e-9);
    // By true depth: the floor is 10 m deep, in the 8-12 m class only.
    EXPECT_NEAR(*MeshCompleteness(samples, truth, 0.2, 0, 91, 8, 12), 55.0 / 105.0, 1e-12);
    EXPECT_FALSE(MeshCompleteness(samples, truth, 0.2, 0, 91, 0, 8).has_value());
    EXPECT_FALSE(MeshCompleteness(samples, truth, 0.2, 0, 91, 12).has_value());
    EXPECT_TRUE(MeshCompleteness(samples, truth, 0.2, 0, 91, 10, 10.5).has_value());  // [A, B)
    EXPECT_FALSE(MeshCompleteness(samples, truth, 0.2, 0, 91, 9, 10).has_value());
    // Lifted 0.3 m above the surface, nothing is within 0.2 m.
    for (auto& p : samples) p.z() += 0.3;
    EXPECT_NEAR(*MeshCompleteness(samples, truth), 0.0, 1e-12);
}

TEST(Scores, DemUncertaintyCountsNodesWithinTheirStatedUncertaintyByClass) {
    const sim::Truth truth = FlatTruth();  // floor at z = -10: slope 0, depth 10 m
    std::vector<Eigen::Vector3d> nodes;
    std::vector<double> unc;
    for (int k = 0; k < 10; ++k) {
        // Errors 0.01 .. 0.10 m against a stated 0.055 m: five within.
        nodes.emplace_back(k - 5.0, 3.0, -10.0 + 0.01 * (k + 1));
        unc.push_back(0.055);
    }
    nodes.emplace_back(1.0, 1.0, std::nan(""));  // empty node: not scored
    unc.push_back(0.1);
    nodes.emplace_back(2.0, 1.0, -10.0);  // no stated uncertainty: not scored
    unc.push_back(std::nan(""));
    const DemUncertaintyScore s = ScoreDemUncertainty(nodes, unc, truth);
    EXPECT_EQ(s.all.count, 10u);
    EXPECT_NEAR(s.all.within, 0.5, 1e-12);
    EXPECT_NEAR(s.all.stated_rms_m, 0.055 / 1.96, 1e-12);
    ASSERT_EQ(s.by_slope.size(), std::size(kSlopeClassEdgesDeg) - 1);
    EXPECT_EQ(s.by_slope[0].count, 10u);  // all on the floor class
    EXPECT_EQ(s.by_slope[2].count, 0u);
    ASSERT_EQ(s.by_depth.size(), std::size(kTpuDepthClassEdgesM) - 1);
    EXPECT_EQ(s.by_depth[2].count, 10u);  // 10 m: the 10-20 m class
    EXPECT_NEAR(s.by_depth[2].within, 0.5, 1e-12);
}

// Soundings placed on the true beam-axis point (straight rays) score no error; through a
// refracting water column the true point is the curved ray's, and the straight ray's point is
// off by what refraction does, so the same soundings are then outside a tight THU.
TEST(Scores, TpuClassesAndTheCurvedTrueRayOfARefractingColumn) {
    sim::Truth truth = FlatTruth();
    truth.terrain.height_m.assign(truth.terrain.height_m.size(), -12.0f);  // a 12 m floor
    for (auto& p : truth.trajectory) {  // level, heading north: the sonar looks down
        p.T_world_vehicle = MakePose(frames::RotationEnuFromNed(), p.T_world_vehicle.translation());
    }
    const sim::PitWorld world(truth.terrain);
    const double deg = M_PI / 180.0;
    const auto& b = truth.boresight;
    const Pose T_vehicle_sonar =
        MakePose(frames::RotationNedFromRpy(b.roll_deg * deg, b.pitch_deg * deg, b.yaw_deg * deg),
                 Eigen::Vector3d(0.8, 0.0, 0.25));
    std::vector<TpuSounding> snd;
    for (int k = 10; k < 90; k += 10) {
        for (double a = -55; a <= 55; a += 5) {
            TpuSounding s;
            s.gps_time_s = 1.4e9 + k;
            s.angle_deg = a;
            const Pose T = *sim::InterpolateTruth(truth.trajectory, s.gps_time_s) * T_vehicle_sonar;
            const Eigen::Vector3d dir =
                T.linear() * Eigen::Vector3d(0, std::sin(a * deg), std::cos(a * deg));
            s.position = T.translation() + *world.RayCast(T.translation(), dir, 100) * dir;
            s.tvu_95_m = 0.01;
            s.thu_95_m = 0.01;
            snd.push_back(s);
        }
    }
    const TpuScore straight = ScoreTpu(snd, truth, world);
    EXPECT_EQ(straight.all.count, snd.size());
    EXPECT_NEAR(straight.all.within_tvu, 1.0, 1e-12);
    ASSERT_EQ(straight.by_angle_class.size(), std::size(kTpuAngleClassEdgesDeg) - 1);
    EXPECT_EQ(straight.by_angle_class[0].count, 8u * 7u);  // |a| 0, 5, 10, 15 (both sides)
    EXPECT_EQ(straight.by_angle_class[3].count, 0u);
    EXPECT_EQ(straight.by_slope[0].count, snd.size());
    EXPECT_EQ(straight.by_depth[2].count, snd.size());  // 12 m: the 10-20 m class
    sim::WaterColumnConfig w;
    w.refraction = true;
    const sim::WaterColumn water(w, 20.0);
    const TpuScore curved = ScoreTpu(snd, truth, world, 1'000'000, &water);
    EXPECT_EQ(curved.all.count, snd.size());
    // The outer beams bend most: their straight-ray points on the floor lie far (horizontally:
    // both are on the floor) from where the curved beam meets it.
    EXPECT_LT(curved.by_angle_class[2].within_thu, 0.2);
    EXPECT_NEAR(curved.by_angle_class[2].within_tvu, 1.0, 1e-12);
    EXPECT_NEAR(straight.by_angle_class[2].within_thu, 1.0, 1e-12);
}

// The common surface of two meshes: the samples in cells that hold samples of both, the same
// cells for either mesh.
TEST(Scores, SharedCellsKeepOnlyTheCommonSurfaceOfBothMeshes) {
    std::vector<Eigen::Vector3d> mine, theirs;
    for (int i = 0; i < 100; ++i) mine.emplace_back(0.1 * i + 0.05, 0.05, 0.05);  // x 0.05..9.95
    for (int i = 0; i < 25; ++i) theirs.emplace_back(0.2 * i + 0.1, 0.15, 0.1);   // x 0.1..4.9
    const auto shared = SamplesInSharedCells(mine, theirs, 0.2);
    ASSERT_EQ(shared.size(), 50u);  // the cells x in [0, 5): two of mine each
    for (const auto& p : shared) EXPECT_LT(p.x(), 5.0);
    // Either way round, the same cells: all of theirs lie in cells of mine.
    EXPECT_EQ(SamplesInSharedCells(theirs, mine, 0.2).size(), theirs.size());
    EXPECT_TRUE(SamplesInSharedCells(mine, {}, 0.2).empty());
    // Another cell: 0.2 m above the first sample's, and at negative coordinates.
    EXPECT_TRUE(SamplesInSharedCells(mine, {Eigen::Vector3d(0.05, 0.05, 0.25)}, 0.2).empty());
    EXPECT_EQ(
        SamplesInSharedCells(
            {Eigen::Vector3d(-0.05, -0.1, -0.19)}, {Eigen::Vector3d(-0.15, -0.01, -0.01)}, 0.2)
            .size(),
        1u);
}

TEST_F(Eval, MissingTruthIsAClearError) {
    const std::string cmd = std::string(PITMAP_BIN_DIR) + "/pitmap-eval --truth '" +
                            (dir_ / "nothing").string() + "' --products '" +
                            (dir_ / "products").string() + "' 2>/dev/null";
    EXPECT_EQ(WEXITSTATUS(std::system(cmd.c_str())), 2);
}

}  // namespace
}  // namespace pitmap::eval
