// SPDX-License-Identifier: MIT
// Georeferencing on a synthetic flat seabed: a level vehicle heading north over water 10 m
// deep; every kept sounding must lie on the plane z = -10 (world up), gaps and spikes counted.
#include "processor/georef/georef.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "common/frames.hpp"

namespace pitmap::proc::georef {
namespace {

constexpr double kDepthM = 10.0;

NavSeries LevelNav(double yaw_deg, std::int64_t t0, int n, std::int64_t step_us) {
    NavSeries nav;
    const LocalTangentFrame world({40.0, -7.0, 100.0});
    for (int i = 0; i < n; ++i) {
        NavSample s;
        s.utime_gps = t0 + i * step_us;
        s.position = world.FromEnu(Eigen::Vector3d(0, 0.1 * i, 0));
        s.yaw_rad = frames::DegToRad(yaw_deg);
        nav.samples.push_back(s);
    }
    return nav;
}

// A ping whose ranges hit the plane z = kDepthM below a sonar at depth `sonar_depth_m`.
void AddFlatPing(PingSeries& s, std::int64_t t, double sonar_depth_m, int beams = 121) {
    PingHeader h;
    h.utime_gps = t;
    h.range_resolution_m = 0.001;
    h.start_angle_deg = -60;
    h.angle_increment_deg = 1.0;
    h.beam_offset = static_cast<std::uint32_t>(s.range_counts.size());
    h.num_beams = static_cast<std::uint16_t>(beams);
    for (int i = 0; i < beams; ++i) {
        const double th = frames::DegToRad(h.start_angle_deg + i * h.angle_increment_deg);
        s.range_counts.push_back(static_cast<std::uint32_t>(
            std::lround((kDepthM - sonar_depth_m) / std::cos(th) / 0.001)));
    }
    s.pings.push_back(h);
}

TEST(Georef, FlatSeabedPointsLieOnThePlane) {
    const NavSeries nav = LevelNav(30.0, 1'000'000'000, 100, 20'000);
    PingSeries pings;
    for (int k = 0; k < 10; ++k) AddFlatPing(pings, 1'000'000'000 + 5'000 + k * 100'000, 0.25);
    SonarMount mount;
    mount.lever_arm_m = Eigen::Vector3d(0.8, 0, 0.25);
    GeorefConfig cfg;
    cfg.max_range_m = 50;
    const GeorefResult r = RunGeoref(nav, pings, mount, cfg);
    ASSERT_EQ(r.counts.pings_georeferenced, 10);
    EXPECT_EQ(r.counts.points, 10 * 121);
    for (const auto& p : r.points.position_world) EXPECT_NEAR(p.z(), -kDepthM, 2e-3);
    // Beam 0 points to port (west of a north-east heading vehicle): starboard positive.
    const Eigen::Vector3d first = r.points.position_world[0];
    const Eigen::Vector3d last = r.points.position_world[120];
    const Eigen::Vector3d stbd(
        std::cos(frames::DegToRad(30.0)), -std::sin(frames::DegToRad(30.0)), 0);
    EXPECT_GT((last - first).dot(stbd), 30.0);
}

// The points are compacted in place when the pings' beams follow each other in the flat
// array; a series laid out otherwise (here the last ping's beams first, with some beams without
// a detection so that compaction moves data) must give the same points.
TEST(Georef, PingsWhoseBeamsAreNotInOrderGiveTheSamePoints) {
    const NavSeries nav = LevelNav(30.0, 1'000'000'000, 100, 20'000);
    PingSeries ordered;
    for (int k = 0; k < 4; ++k) {
        AddFlatPing(ordered, 1'000'000'000 + 5'000 + k * 100'000, 0.25);
    }
    for (std::size_t j = 0; j < ordered.range_counts.size(); j += 7) ordered.range_counts[j] = 0;
    PingSeries reversed;
    reversed.pings = ordered.pings;
    for (int k = 3; k >= 0; --k) {
        const PingHeader& h = ordered.pings[static_cast<std::size_t>(k)];
        reversed.pings[static_cast<std::size_t>(k)].beam_offset =
            static_cast<std::uint32_t>(reversed.range_counts.size());
        reversed.range_counts.insert(reversed.range_counts.end(),
                                     ordered.range_counts.begin() + h.beam_offset,
                                     ordered.range_counts.begin() + h.beam_offset + h.num_beams);
    }
    SonarMount mount;
    mount.lever_arm_m = Eigen::Vector3d(0.8, 0, 0.25);
    GeorefConfig cfg;
    cfg.max_range_m = 50;
    const GeorefResult a = RunGeoref(nav, ordered, mount, cfg);
    const GeorefResult b = RunGeoref(nav, reversed, mount, cfg);
    ASSERT_EQ(a.counts.no_detection, 4 * 121 / 7 + 1);
    ASSERT_GT(a.points.size(), 400u);
    ASSERT_EQ(a.points.size(), b.points.size());
    EXPECT_EQ(a.points.ping, b.points.ping);
    EXPECT_EQ(a.points.beam, b.points.beam);
    EXPECT_EQ(a.points.range_m, b.points.range_m);
    EXPECT_EQ(a.points.angle_rad, b.points.angle_rad);
    for (std::size_t i = 0; i < a.points.size(); ++i) {
        EXPECT_EQ(a.points.position_world[i], b.points.position_world[i]) << i;
        EXPECT_NEAR(a.points.position_world[i].z(), -kDepthM, 2e-3) << i;
    }
}

TEST(Georef, RefusesPingsInNavGapsAndOutsideTheSpan) {
    NavSeries nav = LevelNav(0.0, 0, 10, 20'000);
    NavSeries later = LevelNav(0.0, 2'000'000, 10, 20'000);
    nav.samples.insert(nav.samples.end(), later.samples.begin(), later.samples.end());
    PingSeries pings;
    AddFlatPing(pings, 10'000, 0.0);     // inside
    AddFlatPing(pings, 1'000'000, 0.0);  // in the 1.8 s gap
    AddFlatPing(pings, 9'000'000, 0.0);  // after the end
    const GeorefResult r = RunGeoref(nav, pings, SonarMount{}, GeorefConfig{});
    EXPECT_EQ(r.counts.pings_georeferenced, 1);
    EXPECT_EQ(r.counts.pings_in_nav_gap, 1);
    EXPECT_EQ(r.counts.pings_outside_nav, 1);
}

TEST(Georef, SpikeFilterAndRangeGateAreCounted) {
    const NavSeries nav = LevelNav(0.0, 0, 10, 20'000);
    PingSeries pings;
    AddFlatPing(pings, 10'000, 0.0);
    pings.range_counts[60] = 5000;  // 5 m among 10 m neighbours: a spike
    pings.range_counts[10] = 0;     // no detection
    pings.range_counts[20] = 100;   // 0.1 m: range gate
    const GeorefResult r = RunGeoref(nav, pings, SonarMount{}, GeorefConfig{});
    EXPECT_EQ(r.counts.spikes, 1);
    EXPECT_EQ(r.counts.no_detection, 1);
    EXPECT_EQ(r.counts.range_gate, 1);
    EXPECT_EQ(r.counts.points, 121 - 3);
}

TEST(Georef, BoresightRollTiltsTheSwath) {
    const NavSeries nav = LevelNav(0.0, 0, 10, 20'000);
    PingSeries pings;
    AddFlatPing(pings, 10'000, 0.0);
    SonarMount mount;
    mount.boresight_roll_deg = 2.0;
    GeorefResult r = RunGeoref(nav, pings, mount, GeorefConfig{});
    // With the wrong (unmodelled) roll the flat seabed is no longer flat; re-applying the
    // zero boresight makes it flat again.
    double spread = 0;
    for (const auto& p : r.points.position_world)
        spread = std::max(spread, std::abs(p.z() + kDepthM));
    EXPECT_GT(spread, 0.2);
    Regeoreference(r, SonarMount{});
    for (const auto& p : r.points.position_world) EXPECT_NEAR(p.z(), -kDepthM, 2e-3);
}

TEST(Georef, ConfigValidateListsEveryProblem) {
    GeorefConfig c;
    c.max_nav_gap_s = 0;
    c.max_range_m = -1;
    c.spike_abs_m = 0;
    EXPECT_EQ(c.Validate().size(), 3u);
    EXPECT_TRUE(GeorefConfig{}.Validate().empty());
}

}  // namespace
}  // namespace pitmap::proc::georef

namespace pitmap::proc::georef {
namespace {

// The sonar assumed 1500 m/s; the water is 1450 m/s throughout. A beam formed at theta left
// at asin(sin(theta) 1450 / 1500) and its range is 1500 / 1450 times its path: with the cast
// the soundings lie on the seabed, with straight rays they do not.
TEST(Georef, RefractionCorrectsSteeringAndRange) {
    constexpr double kWater = 1450, kAssumed = 1500, kSonarDepth = 0.25;
    const NavSeries nav = LevelNav(30.0, 1'000'000'000, 100, 20'000);
    PingSeries pings;
    for (int k = 0; k < 5; ++k) {
        PingHeader h;
        h.utime_gps = 1'000'000'000 + 5'000 + k * 100'000;
        h.sound_speed_mps = kAssumed;
        h.sound_speed_valid = true;
        h.range_resolution_m = 0.0001;
        h.start_angle_deg = -60;
        h.angle_increment_deg = 2.0;
        h.beam_offset = static_cast<std::uint32_t>(pings.range_counts.size());
        h.num_beams = 61;
        for (int i = 0; i < h.num_beams; ++i) {
            const double th = frames::DegToRad(h.start_angle_deg + i * h.angle_increment_deg);
            const double th_w = std::asin(std::sin(th) * kWater / kAssumed);
            const double path = (kDepthM - kSonarDepth) / std::cos(th_w);
            pings.range_counts.push_back(
                static_cast<std::uint32_t>(std::lround(path * kAssumed / kWater / 0.0001)));
        }
        pings.pings.push_back(h);
    }
    SonarMount mount;
    mount.lever_arm_m = Eigen::Vector3d(0.8, 0, kSonarDepth);
    GeorefConfig cfg;
    cfg.spike_half_window = 0;
    svp::SoundSpeedCast cast;
    cast.name = "cold";
    cast.depth_m = {0, 30};
    cast.speed_mps = {kWater, kWater};
    auto refr = std::make_shared<const svp::Refraction>(std::vector<svp::SoundSpeedCast>{cast},
                                                        svp::CastSelection::kNearestPreceding,
                                                        svp::SurfaceSpeedSource::kProfile,
                                                        0.0);
    GeorefResult traced = RunGeoref(nav, pings, mount, cfg, std::nullopt, {}, refr);
    const GeorefResult straight = RunGeoref(nav, pings, mount, cfg);
    ASSERT_EQ(traced.counts.points, 5 * 61);
    EXPECT_EQ(traced.counts.refraction_failed, 0);
    double worst_straight = 0;
    for (std::size_t j = 0; j < traced.points.size(); ++j) {
        EXPECT_NEAR(traced.points.position_world[j].z(), -kDepthM, 2e-4) << j;
        worst_straight =
            std::max(worst_straight, std::abs(straight.points.position_world[j].z() + kDepthM));
        // The traced sounding seen from the head maps back onto it.
        const GeorefPing& ping = traced.pings[traced.points.ping[j]];
        const Eigen::Vector3d back =
            ping.T_world_vehicle * mount.T_vehicle_sonar() * SoundingVectorSonar(traced, j);
        EXPECT_NEAR((back - traced.points.position_world[j]).norm(), 0.0, 1e-9);
    }
    EXPECT_GT(worst_straight, 0.3);  // at 60 deg the straight beam misses by decimetres
    // Re-applying the same mount traces to the same soundings (ranges and angles are kept as
    // floats: micrometres).
    const auto before = traced.points.position_world;
    Regeoreference(traced, mount);
    for (std::size_t j = 0; j < before.size(); ++j) {
        EXPECT_NEAR((traced.points.position_world[j] - before[j]).norm(), 0.0, 1e-5);
    }
}

}  // namespace
}  // namespace pitmap::proc::georef
