// SPDX-License-Identifier: MIT
// The conversions between the georeferenced survey and the 3-D stages (processor/pipeline/
// adapters.hpp): SLAM slices and TSDF scans must reproduce the georeferenced soundings exactly,
// corrected poses must move the soundings rigidly, and trajectory CSVs must round-trip.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "common/frames.hpp"
#include "processor/pipeline/adapters.hpp"
#include "processor/pipeline/scan_maker.hpp"

namespace pitmap::proc::pipeline {
namespace {

namespace fs = std::filesystem;

constexpr double kStartDeg = -60.0;
constexpr double kIncrementDeg = 0.25;
constexpr int kBeams = 481;

survey::SonarMount Mount() {
    survey::SonarMount m;
    m.lever_arm_m = Eigen::Vector3d(0.8, -0.1, 0.25);
    m.boresight_roll_deg = 0.4;
    m.boresight_pitch_deg = -0.3;
    m.boresight_yaw_deg = 1.2;
    return m;
}

Pose VehiclePose(int k) {
    return MakePose(frames::RotationWorldFromRpy(0.02 * k, -0.01, 0.3 + 0.05 * k),
                    Eigen::Vector3d(1.2 * k, 0.5 * k, 0.05 * k));
}

// Four pings, the third keeps no sounding; beams every 7th, ranges growing off nadir.
struct Survey {
    georef::GeorefResult geo;
    survey::PingSeries pings;
};

Survey MakeSurvey(const survey::SonarMount& mount) {
    Survey s;
    s.geo.mount = mount;  // as RunGeoref records it
    for (int k = 0; k < 4; ++k) {
        survey::PingHeader h;
        h.utime_gps = 1'400'000'000'000'000 + k * 100'000;
        h.start_angle_deg = kStartDeg;
        h.angle_increment_deg = kIncrementDeg;
        h.profile_tilt_deg = k == 1 ? 2.0 : 0.0;
        h.num_beams = kBeams;
        h.beam_offset = static_cast<std::uint32_t>(k * kBeams);
        s.pings.pings.push_back(h);
        georef::GeorefPing p;
        p.utime_gps = h.utime_gps;
        p.header_index = static_cast<std::uint32_t>(k);
        p.T_world_vehicle = VehiclePose(k);
        p.profile_tilt_rad = frames::DegToRad(h.profile_tilt_deg);
        p.sensor_world = (p.T_world_vehicle * mount.T_vehicle_sonar()).translation();
        s.geo.pings.push_back(p);
        if (k == 2) continue;
        for (int b = 0; b < kBeams; b += 7) {
            const double theta = frames::DegToRad(kStartDeg + b * kIncrementDeg);
            const double r = 20.0 / std::max(0.5, std::cos(theta));
            s.geo.points.position_world.push_back(
                p.T_world_vehicle * mount.T_vehicle_sonar() *
                georef::BeamVectorSonar(r, theta, p.profile_tilt_rad));
            s.geo.points.ping.push_back(static_cast<std::uint32_t>(k));
            s.geo.points.beam.push_back(static_cast<std::uint16_t>(b));
            s.geo.points.range_m.push_back(static_cast<float>(r));
            s.geo.points.angle_rad.push_back(static_cast<float>(theta));
        }
    }
    return s;
}

// R2Sonic-like equi-distant beams (PingSeries::beam_angles_deg) over a flat seabed 10 m down:
// the scan is equally spaced from the first to the last angle and its ranges are the seabed's
// at the new angles (linear interpolation in angle between neighbouring beams).
TEST(Adapters, ScansOfUnequallySpacedBeamsAreResampledToEqualSpacing) {
    constexpr int n = 101;
    constexpr double kDepth = 10.0;
    Survey s;
    survey::PingHeader h;
    h.utime_gps = 1'400'000'000'000'000;
    h.num_beams = n;
    std::vector<double> angle(n);
    for (int b = 0; b < n; ++b) {
        angle[b] = std::atan((-17.0 + 34.0 * b / (n - 1)) / kDepth);
        s.pings.beam_angles_deg.push_back(static_cast<float>(frames::RadToDeg(angle[b])));
    }
    h.start_angle_deg = frames::RadToDeg(angle.front());
    h.angle_increment_deg = frames::RadToDeg(angle.back() - angle.front()) / (n - 1);
    s.pings.pings.push_back(h);
    s.pings.range_counts.assign(n, 1);
    georef::GeorefPing p;
    p.utime_gps = h.utime_gps;
    s.geo.pings.push_back(p);
    for (int b = 0; b < n; ++b) {
        if (b == 50) continue;  // a beam without a sounding at nadir
        s.geo.points.position_world.push_back(Eigen::Vector3d::Zero());
        s.geo.points.ping.push_back(0);
        s.geo.points.beam.push_back(static_cast<std::uint16_t>(b));
        s.geo.points.range_m.push_back(static_cast<float>(kDepth / std::cos(angle[b])));
        s.geo.points.angle_rad.push_back(static_cast<float>(angle[b]));
    }
    const auto scans = MakeScans(s.geo, s.pings, survey::SonarMount{});
    ASSERT_EQ(scans.size(), 1u);
    const auto& scan = scans[0];
    ASSERT_EQ(scan.ranges_m.size(), static_cast<std::size_t>(n));
    EXPECT_NEAR(scan.start_angle_rad, angle.front(), 1e-6);
    EXPECT_NEAR(scan.angle_increment_rad, (angle.back() - angle.front()) / (n - 1), 1e-6);
    int empty = 0;
    for (int j = 0; j < n; ++j) {
        const double th = scan.start_angle_rad + j * static_cast<double>(scan.angle_increment_rad);
        const float r = scan.ranges_m[static_cast<std::size_t>(j)];
        if (r == 0.0f) {
            ++empty;
            EXPECT_LT(std::abs(th), frames::DegToRad(3.0)) << "only around the missing beam";
            continue;
        }
        EXPECT_NEAR(r * std::cos(th), kDepth, 0.02) << "slot " << j;
    }
    EXPECT_LE(empty, 3);
}

TEST(Adapters, SlicesReproduceTheGeoreferencedSoundings) {
    const auto mount = Mount();
    const Survey s = MakeSurvey(mount);
    survey::NavSeries nav;
    const SliceSet set = MakeSlices(s.geo, nav, 1, 5.0, PoseSigma::Constant(0.01));
    ASSERT_EQ(set.slices.size(), 3u) << "the ping without soundings makes no slice";
    EXPECT_EQ(set.ping, (std::vector<std::uint32_t>{0, 1, 3}));
    std::size_t i = 0;
    for (std::size_t j = 0; j < set.slices.size(); ++j) {
        const slam::Slice& sl = set.slices[j];
        EXPECT_DOUBLE_EQ(sl.gps_time_s, s.geo.pings[set.ping[j]].utime_gps * 1e-6);
        for (const Eigen::Vector3f& x : sl.points_vehicle) {
            const Eigen::Vector3d w = sl.T_world_vehicle * x.cast<double>();
            EXPECT_LT((w - s.geo.points.position_world[i]).norm(), 1e-5) << "point " << i;
            ++i;
        }
    }
    EXPECT_EQ(i, s.geo.points.size());
    const SliceSet strided = MakeSlices(s.geo, nav, 4, 5.0, PoseSigma::Constant(0.01));
    EXPECT_EQ(strided.slices[0].points_vehicle.size(),
              (set.slices[0].points_vehicle.size() + 3) / 4);
}

// Two slice sets equal bit for bit: the same pings, times, poses, sigmas and points.
void ExpectSameSlices(const SliceSet& a, const SliceSet& b) {
    ASSERT_EQ(a.slices.size(), b.slices.size());
    EXPECT_EQ(a.ping, b.ping);
    EXPECT_EQ(a.num_points, b.num_points);
    for (std::size_t j = 0; j < a.slices.size(); ++j) {
        const slam::Slice& x = a.slices[j];
        const slam::Slice& y = b.slices[j];
        EXPECT_EQ(x.gps_time_s, y.gps_time_s) << j;
        EXPECT_TRUE(x.T_world_vehicle.matrix() == y.T_world_vehicle.matrix()) << j;
        EXPECT_TRUE(x.pose_sigma == y.pose_sigma) << j;
        ASSERT_EQ(x.points_vehicle.size(), y.points_vehicle.size()) << "slice " << j;
        for (std::size_t i = 0; i < x.points_vehicle.size(); ++i) {
            EXPECT_TRUE(x.points_vehicle[i] == y.points_vehicle[i]) << "slice " << j << " " << i;
        }
    }
}

georef::GeorefPoints PointsOf(const georef::GeorefPoints& p, std::size_t first, std::size_t n) {
    georef::GeorefPoints b;
    const auto take = [&](const auto& from, auto& to) {
        to.assign(from.begin() + static_cast<long>(first),
                  from.begin() + static_cast<long>(first + n));
    };
    take(p.position_world, b.position_world);
    take(p.ping, b.ping);
    take(p.beam, b.beam);
    take(p.range_m, b.range_m);
    take(p.angle_rad, b.angle_rad);
    return b;
}

// SLAM's slices from the view read a block at a time (decision 043) are MakeSlices' of the whole
// view bit for bit, whatever the blocks: one sounding, a few (a ping's soundings straddle several
// blocks, the stride counting on across them), a ping and a bit, the whole view.
TEST(Adapters, SlicesFromBlocksOfTheViewAreTheWholeViewsBitForBit) {
    const Survey s = MakeSurvey(Mount());
    survey::NavSeries nav;
    for (int k = 0; k < 3; ++k) {
        survey::NavStdDev d;
        d.utime_gps = 1'400'000'000'000'000 + k * 150'000;
        d.east_m = 0.1f * static_cast<float>(k + 1);
        d.north_m = d.up_m = 0.2f;
        d.roll_deg = d.pitch_deg = d.yaw_deg = 0.01f * static_cast<float>(k + 1);
        nav.stddevs.push_back(d);
    }
    const std::size_t n = s.geo.points.size();
    for (const int stride : {1, 3, 4}) {
        const SliceSet whole = MakeSlices(s.geo, nav, stride, 5.0, PoseSigma::Constant(0.01));
        ASSERT_EQ(whole.slices.size(), 3u);
        for (const std::size_t block : {std::size_t{1}, std::size_t{5}, std::size_t{71}, n}) {
            SliceBuilder builder(s.geo, nav, stride, 5.0, PoseSigma::Constant(0.01));
            for (std::size_t first = 0; first < n; first += block) {
                const std::size_t count = std::min(block, n - first);
                ASSERT_TRUE(builder.Add(PointsOf(s.geo.points, first, count), first));
            }
            SCOPED_TRACE("stride " + std::to_string(stride) + ", block " + std::to_string(block));
            ExpectSameSlices(builder.Finish(), whole);
        }
    }
    // A block that does not follow the last one is an error; soundings out of ping order give
    // no slices, as MakeSlices.
    SliceBuilder skipped(s.geo, nav, 1, 5.0, PoseSigma::Constant(0.01));
    ASSERT_TRUE(skipped.Add(PointsOf(s.geo.points, 0, 10), 0));
    EXPECT_FALSE(skipped.Add(PointsOf(s.geo.points, 11, 10), 11));
    SliceBuilder unsorted(s.geo, nav, 1, 5.0, PoseSigma::Constant(0.01));
    ASSERT_TRUE(unsorted.Add(PointsOf(s.geo.points, n - 10, 10), 0));
    ASSERT_TRUE(unsorted.Add(PointsOf(s.geo.points, 0, 10), 10));
    EXPECT_TRUE(unsorted.Finish().slices.empty());
}

TEST(Adapters, PoseSigmaComesFromTheNearestStddevRecord) {
    survey::NavSeries nav;
    for (int k = 0; k < 3; ++k) {
        survey::NavStdDev d;
        d.utime_gps = k * 1'000'000;
        d.east_m = 0.1f * static_cast<float>(k + 1);
        d.north_m = 0.2f;
        d.up_m = survey::kNaNf;  // not reported: the fallback takes its place
        d.roll_deg = d.pitch_deg = 0.01f;
        d.yaw_deg = 0.05f;
        nav.stddevs.push_back(d);
    }
    const PoseSigma fallback = PoseSigma::Constant(9.0);
    const PoseSigma a = PoseSigmaAt(nav, 1'400'000, 5.0, fallback);
    EXPECT_NEAR(a[3], 0.2, 1e-6) << "nearest record is the one at 1 s";
    EXPECT_NEAR(a[4], 0.2, 1e-6);
    EXPECT_EQ(a[5], 9.0);
    EXPECT_NEAR(a[2], frames::DegToRad(0.05), 1e-9);
    EXPECT_NEAR(PoseSigmaAt(nav, 1'600'000, 5.0, fallback)[3], 0.3, 1e-6);
    EXPECT_EQ(PoseSigmaAt(nav, 60'000'000, 5.0, fallback), fallback) << "too old";
    EXPECT_EQ(PoseSigmaAt(survey::NavSeries{}, 0, 5.0, fallback), fallback) << "no records";
}

TEST(Adapters, ScansReproduceTheSoundingsAndMarkDroppedBeams) {
    const auto mount = Mount();
    const Survey s = MakeSurvey(mount);
    const auto scans = MakeScans(s.geo, s.pings, mount);
    ASSERT_EQ(scans.size(), 4u);
    for (const auto& scan : scans)
        ASSERT_EQ(scan.ranges_m.size(), static_cast<std::size_t>(kBeams));
    for (std::size_t i = 0; i < s.geo.points.size(); ++i) {
        const auto& scan = scans[s.geo.points.ping[i]];
        const int b = s.geo.points.beam[i];
        const double theta =
            scan.start_angle_rad + b * static_cast<double>(scan.angle_increment_rad);
        const double r = scan.ranges_m[static_cast<std::size_t>(b)];
        const Eigen::Vector3d p =
            scan.T_world_sonar * Eigen::Vector3d(0, r * std::sin(theta), r * std::cos(theta));
        EXPECT_LT((p - s.geo.points.position_world[i]).norm(), 2e-4) << "point " << i;
    }
    EXPECT_EQ(scans[0].ranges_m[1], 0.0f) << "beam 1 has no sounding";
    for (float r : scans[2].ranges_m) EXPECT_EQ(r, 0.0f);
    // Every 3rd ping (the picture before SLAM): pings 0 and 3, the same scans as above.
    const auto thinned = MakeScans(s.geo, s.pings, mount, 3);
    ASSERT_EQ(thinned.size(), 2u);
    for (std::size_t k = 0; k < thinned.size(); ++k) {
        EXPECT_EQ(thinned[k].gps_time_s, scans[3 * k].gps_time_s) << k;
        EXPECT_EQ(thinned[k].ranges_m, scans[3 * k].ranges_m) << k;
        EXPECT_TRUE(thinned[k].T_world_sonar.isApprox(scans[3 * k].T_world_sonar)) << k;
    }
}

// Ten pings of unequally spaced beams (resampled when their scans complete): pings 0, 4, 8 and
// 9 keep no sounding, ping 6 names no header (its scan has a pose and no beams).
Survey SurveyWithGaps() {
    constexpr int n = 41;
    Survey s;
    for (int b = 0; b < n; ++b) {
        s.pings.beam_angles_deg.push_back(
            static_cast<float>(-40.0 + 95.0 * std::pow(b / 40.0, 1.3)));
    }
    for (int k = 0; k < 10; ++k) {
        survey::PingHeader h;
        h.utime_gps = 1'400'000'000'000'000 + k * 100'000;
        h.start_angle_deg = -50.0;
        h.angle_increment_deg = 2.5;
        h.num_beams = n;
        s.pings.pings.push_back(h);
        georef::GeorefPing p;
        p.utime_gps = h.utime_gps;
        p.header_index = k == 6 ? 999u : static_cast<std::uint32_t>(k);
        p.T_world_vehicle = VehiclePose(k);
        p.profile_tilt_rad = 0.01 * k;
        s.geo.pings.push_back(p);
        if (k == 0 || k == 4 || k >= 8) continue;
        for (int b = k % 3; b < n; b += 1 + k % 2) {
            s.geo.points.position_world.push_back(Eigen::Vector3d::Zero());
            s.geo.points.ping.push_back(static_cast<std::uint32_t>(k));
            s.geo.points.beam.push_back(static_cast<std::uint16_t>(b));
            s.geo.points.range_m.push_back(static_cast<float>(10.0 + 0.1 * b + k));
            s.geo.points.angle_rad.push_back(0.0f);
        }
    }
    s.pings.range_counts.assign(s.pings.pings.size() * n, 1);
    return s;
}

// Points [first, first + count) of the view.
georef::GeorefPoints BlockOf(const georef::GeorefPoints& v, std::size_t first, std::size_t count) {
    const std::size_t e = std::min(v.size(), first + count);
    georef::GeorefPoints b;
    for (std::size_t i = first; i < e; ++i) {
        b.position_world.push_back(v.position_world[i]);
        b.ping.push_back(v.ping[i]);
        b.beam.push_back(v.beam[i]);
        b.range_m.push_back(v.range_m[i]);
        b.angle_rad.push_back(v.angle_rad[i]);
    }
    return b;
}

// The scans made from blocks of the view (of 1, 2, 5, 7 and 1 000 points, whole pings or cut
// anywhere, taken after every block or once) are MakeScans' bit for bit, every ping_stride-th
// ping, the pings without soundings and without a header included.
TEST(Adapters, ScansMadeFromBlocksOfTheViewAreTheWholeViewsBitForBit) {
    const Survey s = SurveyWithGaps();
    const auto mount = Mount();
    for (const int stride : {1, 2, 3}) {
        const auto whole = MakeScans(s.geo, s.pings, mount, stride);
        ASSERT_EQ(whole.size(), (10u + stride - 1) / stride);
        for (const std::size_t block : {1u, 2u, 5u, 7u, 1000u}) {
            for (const bool take_each : {true, false}) {
                ScanMaker maker(s.geo.pings, s.pings, mount, stride);
                EXPECT_EQ(maker.num_scans(), whole.size());
                std::vector<fusion::SonarScan> made;
                const auto take = [&] {
                    for (auto& scan : maker.Take()) made.push_back(std::move(scan));
                };
                for (std::size_t first = 0; first < s.geo.points.size(); first += block) {
                    ASSERT_TRUE(maker.Add(BlockOf(s.geo.points, first, block)));
                    if (take_each) take();
                }
                maker.Finish();
                take();
                ASSERT_EQ(made.size(), whole.size()) << stride << " " << block;
                for (std::size_t k = 0; k < whole.size(); ++k) {
                    EXPECT_EQ(made[k].gps_time_s, whole[k].gps_time_s);
                    EXPECT_EQ(made[k].start_angle_rad, whole[k].start_angle_rad);
                    EXPECT_EQ(made[k].angle_increment_rad, whole[k].angle_increment_rad);
                    EXPECT_TRUE(made[k].T_world_sonar.matrix() == whole[k].T_world_sonar.matrix());
                    EXPECT_EQ(made[k].ranges_m, whole[k].ranges_m)
                        << "stride " << stride << ", blocks of " << block << ", scan " << k;
                }
            }
        }
        // A scan is handed over only once complete: after the points of ping 5, ping 5's is not.
        ScanMaker maker(s.geo.pings, s.pings, mount, 1);
        std::size_t through5 = 0;
        while (s.geo.points.ping[through5] <= 5) ++through5;
        ASSERT_TRUE(maker.Add(BlockOf(s.geo.points, 0, through5)));
        EXPECT_EQ(maker.Take().size(), 5u);
    }
    const auto whole = MakeScans(s.geo, s.pings, mount);
    EXPECT_EQ(whole[6].ranges_m.size(), 0u) << "no header";
    EXPECT_EQ(whole[4].ranges_m, std::vector<float>(41, 0.0f)) << "no sounding";
    EXPECT_NE(whole[5].start_angle_rad, static_cast<float>(frames::DegToRad(-50.0))) << "resampled";
}

// Points out of ping order, or of a ping the view has not, are an error naming it.
TEST(Adapters, ScansFromBlocksOutOfPingOrderAreAnError) {
    const Survey s = SurveyWithGaps();
    ScanMaker maker(s.geo.pings, s.pings, Mount());
    georef::GeorefPoints late = BlockOf(s.geo.points, s.geo.points.size() - 1, 1);
    ASSERT_TRUE(maker.Add(late));
    const Status back = maker.Add(BlockOf(s.geo.points, 0, 1));
    ASSERT_FALSE(back);
    EXPECT_NE(back.error().message.find("ping order"), std::string::npos) << back.error().message;
    late.ping[0] = 10;
    EXPECT_FALSE(maker.Add(late));
}

TEST(Adapters, NewVehiclePosesMoveEachPingsSoundingsRigidly) {
    const auto mount = Mount();
    Survey s = MakeSurvey(mount);
    const Survey before = s;
    std::vector<Pose> poses;
    for (const auto& p : s.geo.pings) poses.push_back(p.T_world_vehicle);
    poses[1].translation() += Eigen::Vector3d(1.0, -2.0, 0.5);
    poses[3].linear() =
        poses[3].linear() * Eigen::AngleAxisd(0.01, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    ASSERT_TRUE(ApplyVehiclePoses(s.geo, poses));
    // A pose count that is not one per ping moves nothing and says so.
    Survey short_of_one = before;
    EXPECT_FALSE(ApplyVehiclePoses(short_of_one.geo, {poses.begin(), poses.end() - 1}));
    EXPECT_EQ(short_of_one.geo.points.position_world, before.geo.points.position_world);
    for (std::size_t i = 0; i < s.geo.points.size(); ++i) {
        const std::uint32_t k = s.geo.points.ping[i];
        const Eigen::Vector3d expected = poses[k] * before.geo.pings[k].T_world_vehicle.inverse() *
                                         before.geo.points.position_world[i];
        EXPECT_LT((s.geo.points.position_world[i] - expected).norm(), 1e-9);
        if (k == 0) {
            EXPECT_LT((s.geo.points.position_world[i] - before.geo.points.position_world[i]).norm(),
                      1e-9);
        }
        if (k == 1) {
            EXPECT_LT((s.geo.points.position_world[i] - before.geo.points.position_world[i] -
                       Eigen::Vector3d(1.0, -2.0, 0.5))
                          .norm(),
                      1e-9);
        }
    }
    EXPECT_LT((s.geo.pings[1].sensor_world - before.geo.pings[1].sensor_world -
               Eigen::Vector3d(1.0, -2.0, 0.5))
                  .norm(),
              1e-9);
    // A scan made after the move still reproduces the moved soundings.
    const auto scans = MakeScans(s.geo, s.pings, mount);
    for (std::size_t i = 0; i < s.geo.points.size(); ++i) {
        const auto& scan = scans[s.geo.points.ping[i]];
        const double th = scan.start_angle_rad +
                          s.geo.points.beam[i] * static_cast<double>(scan.angle_increment_rad);
        const double r = s.geo.points.range_m[i];
        EXPECT_LT((scan.T_world_sonar * Eigen::Vector3d(0, r * std::sin(th), r * std::cos(th)) -
                   s.geo.points.position_world[i])
                      .norm(),
                  2e-4);
    }
}

TEST(Adapters, PosesAtPingsMatchesInterpolatesAndCountsPingsOutside) {
    const auto mount = Mount();
    const Survey s = MakeSurvey(mount);
    const double t0 = s.geo.pings[0].utime_gps * 1e-6;
    // Samples at pings 0 and 2 only: ping 1 is interpolated halfway; ping 3 is outside.
    const std::vector<double> t = {t0, t0 + 0.2};
    const Pose a = MakePose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, 0));
    const Pose b = MakePose(Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitZ()).toRotationMatrix(),
                            Eigen::Vector3d(2, 4, -1));
    const PoseLookup r = PosesAtPings(s.geo, t, {a, b});
    ASSERT_EQ(r.T_world_vehicle.size(), 4u);
    EXPECT_EQ(r.outside_span, 1u);
    EXPECT_LT((r.T_world_vehicle[0].translation() - a.translation()).norm(), 1e-12);
    EXPECT_LT((r.T_world_vehicle[1].translation() - Eigen::Vector3d(1, 2, -0.5)).norm(), 2e-5)
        << "GPS seconds near 1.4e9 carry ~0.2 us";
    EXPECT_NEAR(Eigen::AngleAxisd(r.T_world_vehicle[1].linear()).angle(), 0.1, 1e-6);
    EXPECT_LT((r.T_world_vehicle[2].translation() - b.translation()).norm(), 1e-12);
    EXPECT_TRUE(r.T_world_vehicle[3].isApprox(s.geo.pings[3].T_world_vehicle))
        << "outside keeps its pose";
}

class TrajectoryCsv : public ::testing::Test {
protected:
    void SetUp() override {
        dir_ = fs::temp_directory_path() / ("pitmap_adapters_" + std::to_string(::getpid()));
        fs::create_directories(dir_);
    }
    void TearDown() override { fs::remove_all(dir_); }
    fs::path dir_;
};

TEST_F(TrajectoryCsv, RoundTripsToSubMillimetre) {
    const auto mount = Mount();
    const Survey s = MakeSurvey(mount);
    const TimedPoses t = PingPoses(s.geo);
    const std::string path = (dir_ / "trajectory.csv").string();
    ASSERT_TRUE(WriteTrajectoryCsv(path, t).ok());
    const auto back = ReadTrajectoryCsv(path);
    ASSERT_TRUE(back.ok()) << back.error().message;
    ASSERT_EQ(back->gps_time_s.size(), t.gps_time_s.size());
    for (std::size_t i = 0; i < t.gps_time_s.size(); ++i) {
        EXPECT_NEAR(back->gps_time_s[i], t.gps_time_s[i], 1e-6);
        EXPECT_LT(
            (back->T_world_vehicle[i].translation() - t.T_world_vehicle[i].translation()).norm(),
            2e-5);
        EXPECT_LT(Eigen::AngleAxisd(back->T_world_vehicle[i].linear().transpose() *
                                    t.T_world_vehicle[i].linear())
                      .angle(),
                  1e-6);
    }
}

TEST_F(TrajectoryCsv, MalformedFilesAreErrorsNamingTheLine) {
    const std::string path = (dir_ / "bad.csv").string();
    std::ofstream(path) << "time,x\n1,2\n";
    auto r = ReadTrajectoryCsv(path);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.error().message.find("not a trajectory CSV"), std::string::npos);
    std::ofstream(path) << "gps_time_s,x_m,y_m,z_m,roll_deg,pitch_deg,yaw_deg\n"
                        << "1.0,0,0,0,0,0,0\n0.5,0,0,0,0,0,0\n";
    r = ReadTrajectoryCsv(path);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.error().message.find(":3: times not increasing"), std::string::npos)
        << r.error().message;
    std::ofstream(path) << "gps_time_s,x_m,y_m,z_m,roll_deg,pitch_deg,yaw_deg\n1.0,0,nan,0,0,0,0\n";
    EXPECT_FALSE(ReadTrajectoryCsv(path).ok());
    EXPECT_FALSE(ReadTrajectoryCsv((dir_ / "missing.csv").string()).ok());
}

// Case 5 of issue 14: trajectory.csv sets the TSDF's extent, so a position of 1e9 m made
// `pitmap fuse` fail inside std::vector ("cannot create std::vector larger than max_size()").
// Implausible or non-finite values are errors naming the file and the line.
TEST_F(TrajectoryCsv, ImplausibleValuesAreErrorsNamingFileAndLine) {
    const std::string path = (dir_ / "trajectory.csv").string();
    const std::string header = "gps_time_s,x_m,y_m,z_m,roll_deg,pitch_deg,yaw_deg\n";
    const std::string good = "1.0,10,20,-3,1,2,3\n";
    for (const char* row : {"2.0,1e9,0,0,0,0,0",
                            "2.0,0,-60000,0,0,0,0",
                            "2.0,0,0,1e300,0,0,0",
                            "2.0,0,0,0,1e5,0,0",
                            "2.0,0,0,0,0,0,-1e300",
                            "1e300,0,0,0,0,0,0",
                            "2.0,inf,0,0,0,0,0",
                            "2.0,0,0,nan,0,0,0",
                            "2.0,1,2",
                            ""}) {
        std::ofstream(path, std::ios::trunc) << header << good << row << (row[0] ? "\n" : "x\n");
        const auto r = ReadTrajectoryCsv(path);
        ASSERT_FALSE(r.ok()) << row;
        EXPECT_NE(r.error().message.find(path + ":3:"), std::string::npos)
            << row << ": " << r.error().message;
    }
    std::ofstream(path, std::ios::trunc) << header << good << "2.0,0,49999,-50000,-720,0,719\n";
    EXPECT_TRUE(ReadTrajectoryCsv(path).ok()) << "values at the limits are accepted";
    std::ofstream(path, std::ios::trunc) << "";
    const auto empty = ReadTrajectoryCsv(path);
    ASSERT_FALSE(empty.ok());
    EXPECT_NE(empty.error().message.find(path), std::string::npos);
}

}  // namespace
}  // namespace pitmap::proc::pipeline
