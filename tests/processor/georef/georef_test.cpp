// SPDX-License-Identifier: MIT
// Georeferencing on a synthetic flat seabed: a level vehicle heading north over water 10 m
// deep; every kept sounding must lie on the plane z = -10 (world up), gaps and spikes counted.
#include "processor/georef/georef.hpp"
#include "processor/georef/georef_blocks.hpp"
#include "processor/georef/survey_view.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <map>
#include <memory>
#include <optional>
#include <type_traits>
#include <utility>
#include <vector>

#include "common/frames.hpp"

namespace pitmap::proc::georef {
namespace {

constexpr double kDepthM = 10.0;

survey::NavSeries LevelNav(double yaw_deg, std::int64_t t0, int n, std::int64_t step_us) {
    survey::NavSeries nav;
    const LocalTangentFrame world({40.0, -7.0, 100.0});
    for (int i = 0; i < n; ++i) {
        survey::NavSample s;
        s.utime_gps = t0 + i * step_us;
        s.position = world.FromEnu(Eigen::Vector3d(0, 0.1 * i, 0));
        s.yaw_rad = frames::DegToRad(yaw_deg);
        nav.samples.push_back(s);
    }
    return nav;
}

// A ping whose ranges hit the plane z = kDepthM below a sonar at depth `sonar_depth_m`.
void AddFlatPing(survey::PingSeries& s, std::int64_t t, double sonar_depth_m, int beams = 121) {
    survey::PingHeader h;
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
    const survey::NavSeries nav = LevelNav(30.0, 1'000'000'000, 100, 20'000);
    survey::PingSeries pings;
    for (int k = 0; k < 10; ++k) AddFlatPing(pings, 1'000'000'000 + 5'000 + k * 100'000, 0.25);
    survey::SonarMount mount;
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
    const survey::NavSeries nav = LevelNav(30.0, 1'000'000'000, 100, 20'000);
    survey::PingSeries ordered;
    for (int k = 0; k < 4; ++k) {
        AddFlatPing(ordered, 1'000'000'000 + 5'000 + k * 100'000, 0.25);
    }
    for (std::size_t j = 0; j < ordered.range_counts.size(); j += 7) ordered.range_counts[j] = 0;
    survey::PingSeries reversed;
    reversed.pings = ordered.pings;
    for (int k = 3; k >= 0; --k) {
        const survey::PingHeader& h = ordered.pings[static_cast<std::size_t>(k)];
        reversed.pings[static_cast<std::size_t>(k)].beam_offset =
            static_cast<std::uint32_t>(reversed.range_counts.size());
        reversed.range_counts.insert(reversed.range_counts.end(),
                                     ordered.range_counts.begin() + h.beam_offset,
                                     ordered.range_counts.begin() + h.beam_offset + h.num_beams);
    }
    survey::SonarMount mount;
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
    survey::NavSeries nav = LevelNav(0.0, 0, 10, 20'000);
    survey::NavSeries later = LevelNav(0.0, 2'000'000, 10, 20'000);
    nav.samples.insert(nav.samples.end(), later.samples.begin(), later.samples.end());
    survey::PingSeries pings;
    AddFlatPing(pings, 10'000, 0.0);     // inside
    AddFlatPing(pings, 1'000'000, 0.0);  // in the 1.8 s gap
    AddFlatPing(pings, 9'000'000, 0.0);  // after the end
    const GeorefResult r = RunGeoref(nav, pings, survey::SonarMount{}, GeorefConfig{});
    EXPECT_EQ(r.counts.pings_georeferenced, 1);
    EXPECT_EQ(r.counts.pings_in_nav_gap, 1);
    EXPECT_EQ(r.counts.pings_outside_nav, 1);
}

// A latency correction moves the first ping a few ms before the INS's first sample when the
// navigation starts with the sonar (the simulator's quarry: -1.3 ms, ping 0 left out): within
// max_nav_extrapolation_s the end samples' motion is carried on; further out the ping is
// refused and counted.
TEST(Georef, PlacesPingsJustOutsideTheSpanByExtrapolation) {
    // North at 5 m/s (0.1 m per 20 ms sample) from t = 1 s to 1.18 s.
    const survey::NavSeries nav = LevelNav(0.0, 1'000'000, 10, 20'000);
    survey::PingSeries pings;
    AddFlatPing(pings, 1'000'000 - 1'300, 0.0);   // 1.3 ms before the first sample
    AddFlatPing(pings, 1'180'000 + 4'000, 0.0);   // 4 ms after the last
    AddFlatPing(pings, 1'000'000 - 50'000, 0.0);  // 50 ms before: too far
    AddFlatPing(pings, 1'180'000 + 30'000, 0.0);  // 30 ms after: too far
    const GeorefResult r = RunGeoref(nav, pings, survey::SonarMount{}, GeorefConfig{});
    ASSERT_EQ(r.counts.pings_georeferenced, 2);
    EXPECT_EQ(r.counts.pings_outside_nav, 2);
    EXPECT_EQ(r.counts.pings_in_nav_gap, 0);
    EXPECT_EQ(r.pings[0].header_index, 0u);
    EXPECT_EQ(r.pings[1].header_index, 1u);
    // Where the vehicle was: 6.5 mm south of the first sample, 20 mm north of the last.
    EXPECT_NEAR(r.pings[0].T_world_vehicle.translation().y(), -0.0065, 1e-6);
    EXPECT_NEAR(r.pings[1].T_world_vehicle.translation().y(), 0.9 + 0.02, 1e-6);
    for (const auto& p : r.points.position_world) EXPECT_NEAR(p.z(), -kDepthM, 2e-3);

    GeorefConfig within_span;
    within_span.max_nav_extrapolation_s = 0;
    EXPECT_EQ(RunGeoref(nav, pings, survey::SonarMount{}, within_span).counts.pings_outside_nav, 4);
    // The end samples further apart than max_nav_gap_s: no motion to carry on (the pings
    // inside the span are in the gap).
    const survey::NavSeries sparse = LevelNav(0.0, 1'000'000, 2, 600'000);
    const GeorefResult g = RunGeoref(sparse, pings, survey::SonarMount{}, GeorefConfig{});
    EXPECT_EQ(g.counts.pings_georeferenced, 0);
    EXPECT_EQ(g.counts.pings_outside_nav, 2);
    EXPECT_EQ(g.counts.pings_in_nav_gap, 2);
}

TEST(Georef, SpikeFilterAndRangeGateAreCounted) {
    const survey::NavSeries nav = LevelNav(0.0, 0, 10, 20'000);
    survey::PingSeries pings;
    AddFlatPing(pings, 10'000, 0.0);
    pings.range_counts[60] = 5000;  // 5 m among 10 m neighbours: a spike
    pings.range_counts[10] = 0;     // no detection
    pings.range_counts[20] = 100;   // 0.1 m: range gate
    const GeorefResult r = RunGeoref(nav, pings, survey::SonarMount{}, GeorefConfig{});
    EXPECT_EQ(r.counts.spikes, 1);
    EXPECT_EQ(r.counts.no_detection, 1);
    EXPECT_EQ(r.counts.range_gate, 1);
    EXPECT_EQ(r.counts.points, 121 - 3);
}

TEST(Georef, BoresightRollTiltsTheSwath) {
    const survey::NavSeries nav = LevelNav(0.0, 0, 10, 20'000);
    survey::PingSeries pings;
    AddFlatPing(pings, 10'000, 0.0);
    survey::SonarMount mount;
    mount.boresight_roll_deg = 2.0;
    GeorefResult r = RunGeoref(nav, pings, mount, GeorefConfig{});
    // With the wrong (unmodelled) roll the flat seabed is no longer flat; re-applying the
    // zero boresight makes it flat again.
    double spread = 0;
    for (const auto& p : r.points.position_world)
        spread = std::max(spread, std::abs(p.z() + kDepthM));
    EXPECT_GT(spread, 0.2);
    Regeoreference(r, survey::SonarMount{});
    for (const auto& p : r.points.position_world) EXPECT_NEAR(p.z(), -kDepthM, 2e-3);
}

TEST(Georef, ConfigValidateListsEveryProblem) {
    GeorefConfig c;
    c.max_nav_gap_s = 0;
    c.max_range_m = -1;
    c.spike_abs_m = 0;
    c.max_nav_extrapolation_s = -0.01;
    EXPECT_EQ(c.Validate().size(), 4u);
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
    const survey::NavSeries nav = LevelNav(30.0, 1'000'000'000, 100, 20'000);
    survey::PingSeries pings;
    for (int k = 0; k < 5; ++k) {
        survey::PingHeader h;
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
    survey::SonarMount mount;
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

// Issue 35: the statuses of soundings. Georef's own verdicts (no detection, range gate, spike)
// and the flags decided elsewhere (the cleaning, the hand edits) resolve into one status per
// sounding (Resolve); the views return the soundings by that status.
namespace pitmap::proc::georef {
namespace {

constexpr std::size_t kBeams = 121;
constexpr std::size_t kNoDetectionBeam = 10;
constexpr std::size_t kRangeGateBeam = 20;
constexpr std::size_t kSpikeBeam = 60;

// Two pings over the flat seabed with one sounding of each of georef's own rejections, and a
// third ping after the end of the navigation (never georeferenced).
struct StatusSurvey {
    survey::NavSeries nav = LevelNav(0.0, 0, 10, 20'000);
    survey::PingSeries pings;
    StatusSurvey() {
        for (std::int64_t t : {10'000, 50'000, 9'000'000}) {
            const std::size_t at = pings.range_counts.size();
            AddFlatPing(pings, t, 0.0, static_cast<int>(kBeams));
            pings.range_counts[at + kNoDetectionBeam] = 0;  // no detection
            pings.range_counts[at + kRangeGateBeam] = 100;  // 0.1 m: range gate
            pings.range_counts[at + kSpikeBeam] = 5000;     // 5 m among 10 m: a spike
        }
    }
    survey::SoundingFlags NoFlags() const {
        survey::SoundingFlags f;
        f.cleaning.assign(pings.range_counts.size(), 0);
        f.manual.assign(pings.range_counts.size(), 0);
        return f;
    }
    GeorefResult Run(const survey::SoundingFlags* flags, survey::SoundingView view) const {
        return RunGeoref(
            nav, pings, survey::SonarMount{}, GeorefConfig{}, {}, {}, nullptr, flags, view);
    }
};

// The soundings of a view: (ping, beam) -> status (0 in the accepted view, which has none).
std::map<std::pair<std::uint32_t, std::uint16_t>, int> Soundings(const GeorefResult& r) {
    std::map<std::pair<std::uint32_t, std::uint16_t>, int> out;
    for (std::size_t j = 0; j < r.points.size(); ++j) {
        const int status = r.points.status.empty() ? 0 : r.points.status[j];
        const bool fresh =
            out.emplace(std::pair{r.points.ping[j], r.points.beam[j]}, status).second;
        EXPECT_TRUE(fresh) << "ping " << r.points.ping[j] << " beam " << r.points.beam[j];
    }
    return out;
}

std::optional<int> StatusOf(const GeorefResult& r, std::uint32_t ping, std::size_t beam) {
    const auto s = Soundings(r);
    const auto it = s.find({ping, static_cast<std::uint16_t>(beam)});
    if (it == s.end()) return std::nullopt;
    return it->second;
}

constexpr int Code(survey::SoundingStatus s) {
    return static_cast<int>(s);
}

// The counts per status cover every sounding of the georeferenced pings (not the refused one)
// once, and the named counters are their sums.
void ExpectCountsAddUp(const GeorefResult& r) {
    std::int64_t total = 0;
    for (const std::int64_t n : r.counts.status) total += n;
    EXPECT_EQ(r.counts.pings_georeferenced, 2);
    EXPECT_EQ(total, 2 * static_cast<std::int64_t>(kBeams));
    EXPECT_EQ(r.counts.no_detection, r.counts.status[Code(survey::SoundingStatus::kNoDetection)]);
    EXPECT_EQ(r.counts.range_gate, r.counts.status[Code(survey::SoundingStatus::kRangeGate)]);
    EXPECT_EQ(r.counts.spikes, r.counts.status[Code(survey::SoundingStatus::kSpike)]);
    EXPECT_EQ(r.counts.manual, r.counts.status[Code(survey::SoundingStatus::kManual)]);
    std::int64_t cleaned = 0;
    for (int code = 0; code < survey::kNumSoundingStatus; ++code) {
        if (survey::IsCleaningStatus(static_cast<survey::SoundingStatus>(code)))
            cleaned += r.counts.status[code];
    }
    EXPECT_EQ(r.counts.cleaned, cleaned);
    EXPECT_EQ(r.counts.points, static_cast<std::int64_t>(r.points.size()));
}

TEST(GeorefViews, ASpikeIsRejectedNotAccepted) {
    const StatusSurvey s;
    const GeorefResult acc = s.Run(nullptr, survey::SoundingView::kAccepted);
    const GeorefResult rej = s.Run(nullptr, survey::SoundingView::kRejected);
    EXPECT_TRUE(acc.points.status.empty());
    ASSERT_EQ(rej.points.status.size(), rej.points.size());
    for (std::uint32_t ping : {0u, 1u}) {
        EXPECT_FALSE(StatusOf(acc, ping, kSpikeBeam)) << ping;
        EXPECT_EQ(StatusOf(rej, ping, kSpikeBeam), Code(survey::SoundingStatus::kSpike)) << ping;
        EXPECT_EQ(StatusOf(rej, ping, kRangeGateBeam), Code(survey::SoundingStatus::kRangeGate))
            << ping;
        // Without a range there is no position: in neither view.
        EXPECT_FALSE(StatusOf(acc, ping, kNoDetectionBeam)) << ping;
        EXPECT_FALSE(StatusOf(rej, ping, kNoDetectionBeam)) << ping;
    }
    EXPECT_EQ(rej.points.size(), 4u);
    EXPECT_EQ(acc.points.size(), 2 * (kBeams - 3));
    // The two views are the same soundings at the same places, split by status.
    for (std::size_t j = 0; j < rej.points.size(); ++j) {
        EXPECT_FALSE(StatusOf(acc, rej.points.ping[j], rej.points.beam[j]));
    }
    for (const GeorefResult* r : {&acc, &rej}) {
        ExpectCountsAddUp(*r);
        EXPECT_EQ(r->counts.spikes, 2);
        EXPECT_EQ(r->counts.range_gate, 2);
        EXPECT_EQ(r->counts.no_detection, 2);
        EXPECT_EQ(r->counts.status[0], 2 * static_cast<std::int64_t>(kBeams - 3));
    }
}

TEST(GeorefViews, AManualRestoreOverridesTheSpikeAndTheRangeGateNeverNoDetection) {
    const StatusSurvey s;
    survey::SoundingFlags f = s.NoFlags();
    for (std::size_t beam : {kNoDetectionBeam, kRangeGateBeam, kSpikeBeam}) {
        f.manual[beam] = static_cast<std::uint8_t>(survey::ManualEdit::kRestore);  // ping 0 only
    }
    const GeorefResult acc = s.Run(&f, survey::SoundingView::kAccepted);
    const GeorefResult rej = s.Run(&f, survey::SoundingView::kRejected);
    const GeorefResult cand = s.Run(&f, survey::SoundingView::kCandidates);
    for (const GeorefResult* r : {&acc, &cand}) {
        EXPECT_EQ(StatusOf(*r, 0, kSpikeBeam), 0);
        EXPECT_EQ(StatusOf(*r, 0, kRangeGateBeam), 0);
        EXPECT_FALSE(StatusOf(*r, 0, kNoDetectionBeam));
        // The other ping's are not restored.
        EXPECT_FALSE(StatusOf(*r, 1, kSpikeBeam));
        EXPECT_FALSE(StatusOf(*r, 1, kRangeGateBeam));
    }
    EXPECT_FALSE(StatusOf(rej, 0, kSpikeBeam));
    EXPECT_FALSE(StatusOf(rej, 0, kRangeGateBeam));
    EXPECT_EQ(StatusOf(rej, 1, kSpikeBeam), Code(survey::SoundingStatus::kSpike));
    EXPECT_EQ(acc.points.size(), 2 * (kBeams - 3) + 2);
    for (const GeorefResult* r : {&acc, &rej, &cand}) {
        ExpectCountsAddUp(*r);
        EXPECT_EQ(r->counts.spikes, 1);
        EXPECT_EQ(r->counts.range_gate, 1);
        EXPECT_EQ(r->counts.no_detection, 2);
        EXPECT_EQ(r->counts.manual, 0);
    }
}

TEST(GeorefViews, AManualRejectMovesAnAcceptedSoundingToTheRejectedView) {
    const StatusSurvey s;
    survey::SoundingFlags f = s.NoFlags();
    const std::size_t beam = 30;
    f.manual[kBeams + beam] = static_cast<std::uint8_t>(survey::ManualEdit::kReject);  // ping 1
    // A manual reject of a spike: georef's own verdict stays the reason.
    f.manual[kSpikeBeam] = static_cast<std::uint8_t>(survey::ManualEdit::kReject);
    const GeorefResult acc = s.Run(&f, survey::SoundingView::kAccepted);
    const GeorefResult rej = s.Run(&f, survey::SoundingView::kRejected);
    const GeorefResult cand = s.Run(&f, survey::SoundingView::kCandidates);
    EXPECT_FALSE(StatusOf(acc, 1, beam));
    EXPECT_EQ(StatusOf(acc, 0, beam), 0);
    EXPECT_EQ(StatusOf(rej, 1, beam), Code(survey::SoundingStatus::kManual));
    EXPECT_FALSE(StatusOf(rej, 0, beam));
    EXPECT_EQ(StatusOf(rej, 0, kSpikeBeam), Code(survey::SoundingStatus::kSpike));
    // What the cleaning decides on leaves out what was rejected by hand.
    EXPECT_FALSE(StatusOf(cand, 1, beam));
    EXPECT_EQ(StatusOf(cand, 0, beam), 0);
    // The rejected sounding is georeferenced like the others (on the seabed).
    for (std::size_t j = 0; j < rej.points.size(); ++j) {
        if (rej.points.status[j] == Code(survey::SoundingStatus::kManual)) {
            EXPECT_NEAR(rej.points.position_world[j].z(), -kDepthM, 2e-3);
        }
    }
    for (const GeorefResult* r : {&acc, &rej, &cand}) {
        ExpectCountsAddUp(*r);
        EXPECT_EQ(r->counts.manual, 1);
        EXPECT_EQ(r->counts.spikes, 2);
    }
}

TEST(GeorefViews, ACleaningStatusRejectsButStaysACandidate) {
    const StatusSurvey s;
    survey::SoundingFlags f = s.NoFlags();
    f.cleaning[40] = static_cast<std::uint8_t>(survey::SoundingStatus::kFreeSpace);
    f.cleaning[kBeams + 41] = static_cast<std::uint8_t>(survey::SoundingStatus::kProfile);
    // The cleaning's verdict on a spike: georef's own verdict stays, and it is no candidate.
    f.cleaning[kSpikeBeam] = static_cast<std::uint8_t>(survey::SoundingStatus::kCluster);
    // A sounding both cleaned and rejected by hand: the hand wins, and it is no candidate.
    f.cleaning[50] = static_cast<std::uint8_t>(survey::SoundingStatus::kMultipath);
    f.manual[50] = static_cast<std::uint8_t>(survey::ManualEdit::kReject);
    // A sounding cleaned and restored by hand: accepted.
    f.cleaning[kBeams + 51] = static_cast<std::uint8_t>(survey::SoundingStatus::kMultipath);
    f.manual[kBeams + 51] = static_cast<std::uint8_t>(survey::ManualEdit::kRestore);
    const GeorefResult acc = s.Run(&f, survey::SoundingView::kAccepted);
    const GeorefResult rej = s.Run(&f, survey::SoundingView::kRejected);
    const GeorefResult cand = s.Run(&f, survey::SoundingView::kCandidates);

    EXPECT_FALSE(StatusOf(acc, 0, 40));
    EXPECT_FALSE(StatusOf(acc, 1, 41));
    EXPECT_EQ(StatusOf(rej, 0, 40), Code(survey::SoundingStatus::kFreeSpace));
    EXPECT_EQ(StatusOf(rej, 1, 41), Code(survey::SoundingStatus::kProfile));
    EXPECT_EQ(StatusOf(cand, 0, 40), Code(survey::SoundingStatus::kFreeSpace));
    EXPECT_EQ(StatusOf(cand, 1, 41), Code(survey::SoundingStatus::kProfile));

    EXPECT_EQ(StatusOf(rej, 0, kSpikeBeam), Code(survey::SoundingStatus::kSpike));
    EXPECT_FALSE(StatusOf(cand, 0, kSpikeBeam));

    EXPECT_EQ(StatusOf(rej, 0, 50), Code(survey::SoundingStatus::kManual));
    EXPECT_FALSE(StatusOf(cand, 0, 50));
    EXPECT_FALSE(StatusOf(acc, 0, 50));

    EXPECT_EQ(StatusOf(acc, 1, 51), 0);
    EXPECT_EQ(StatusOf(cand, 1, 51), 0);
    EXPECT_FALSE(StatusOf(rej, 1, 51));

    // Candidates: every accepted sounding and the two cleaned ones, nothing else.
    EXPECT_EQ(cand.points.size(), acc.points.size() + 2);
    for (std::size_t j = 0; j < acc.points.size(); ++j) {
        EXPECT_EQ(StatusOf(cand, acc.points.ping[j], acc.points.beam[j]), 0);
    }
    for (const GeorefResult* r : {&acc, &rej, &cand}) {
        ExpectCountsAddUp(*r);
        EXPECT_EQ(r->counts.cleaned, 2);
        EXPECT_EQ(r->counts.manual, 1);
        EXPECT_EQ(r->counts.spikes, 2);
        EXPECT_EQ(r->counts.status[Code(survey::SoundingStatus::kFreeSpace)], 1);
        EXPECT_EQ(r->counts.status[Code(survey::SoundingStatus::kProfile)], 1);
        EXPECT_EQ(r->counts.status[Code(survey::SoundingStatus::kCluster)], 0);
        EXPECT_EQ(r->counts.status[Code(survey::SoundingStatus::kMultipath)], 0);
    }
}

// Resolve on its own, over every pair of a georef verdict and the flags.
TEST(GeorefViews, ResolveOrdersTheVerdicts) {
    survey::SoundingFlags f;
    f.cleaning = {0, static_cast<std::uint8_t>(survey::SoundingStatus::kCluster)};
    f.manual = {0, 0, static_cast<std::uint8_t>(survey::ManualEdit::kReject)};
    using S = survey::SoundingStatus;
    // Beyond the vectors: nothing decided.
    EXPECT_EQ(survey::Resolve(S::kAccepted, f, 7), S::kAccepted);
    EXPECT_EQ(survey::Resolve(S::kAccepted, f, 1), S::kCluster);
    EXPECT_EQ(survey::Resolve(S::kSpike, f, 1), S::kSpike);
    EXPECT_EQ(survey::Resolve(S::kAccepted, f, 2), S::kManual);
    EXPECT_EQ(survey::Resolve(S::kRangeGate, f, 2), S::kRangeGate);
    f.manual = {static_cast<std::uint8_t>(survey::ManualEdit::kRestore),
                static_cast<std::uint8_t>(survey::ManualEdit::kRestore)};
    for (S own : {S::kAccepted, S::kRangeGate, S::kSpike}) {
        EXPECT_EQ(survey::Resolve(own, f, 0), S::kAccepted) << ToString(own);
        EXPECT_EQ(survey::Resolve(own, f, 1), S::kAccepted) << ToString(own);
    }
    EXPECT_EQ(survey::Resolve(S::kNoDetection, f, 0), S::kNoDetection);
    EXPECT_EQ(survey::Resolve(S::kRefraction, f, 1), S::kRefraction);
}

}  // namespace
}  // namespace pitmap::proc::georef

// Decision 033: georef a block of pings at a time (RunGeorefByBlocks) gives RunGeoref's view bit
// for bit, its pings and its counts, whatever the block, in every view, with and without
// refraction; and the new mount on blocks (Remount) is Regeoreference's.
namespace pitmap::proc::georef {
namespace {

// 300 pings of 121 beams over a wavy floor from a rolling vehicle: no detections, spikes,
// range-gated beams, a navigation gap and pings after the navigation, the cleaning's and the
// hand's flags on some soundings.
struct BlockSurvey {
    survey::NavSeries nav;
    survey::PingSeries pings;
    survey::SoundingFlags flags;
    BlockSurvey() {
        const LocalTangentFrame world({40.0, -7.0, 100.0});
        for (int i = 0; i < 2000; ++i) {
            if (i >= 900 && i < 940) continue;  // a 0.8 s gap
            survey::NavSample s;
            s.utime_gps = 1'000'000'000 + i * 20'000;
            s.position = world.FromEnu(Eigen::Vector3d(0.01 * i, 0.1 * i, 0.02 * std::sin(i)));
            s.roll_rad = 0.05 * std::sin(i * 0.03);
            s.pitch_rad = 0.03 * std::cos(i * 0.05);
            s.yaw_rad = 0.4 + 0.001 * i;
            nav.samples.push_back(s);
        }
        for (int k = 0; k < 300; ++k) {
            survey::PingHeader h;
            h.utime_gps = 1'000'000'000 + 7'000 + k * 140'000;
            h.sound_speed_mps = 1490;
            h.sound_speed_valid = true;
            h.range_resolution_m = 0.001;
            h.start_angle_deg = -60;
            h.angle_increment_deg = 1.0;
            h.profile_tilt_deg = k % 7 == 0 ? 1.5 : 0.0;
            h.beam_offset = static_cast<std::uint32_t>(pings.range_counts.size());
            h.num_beams = 121;
            for (int i = 0; i < 121; ++i) {
                const double th = frames::DegToRad(-60.0 + i);
                const double depth = 10.0 + 0.5 * std::sin(0.1 * k + 0.07 * i);
                std::uint32_t c =
                    static_cast<std::uint32_t>(std::lround(depth / std::cos(th) / 0.001));
                if ((k * 121 + i) % 97 == 0) c = 0;      // no detection
                if ((k * 121 + i) % 89 == 0) c = c / 2;  // a spike
                if ((k * 121 + i) % 211 == 0) c = 200;   // 0.2 m: range gate
                pings.range_counts.push_back(c);
            }
            pings.pings.push_back(h);
        }
        flags.cleaning.assign(pings.range_counts.size(), 0);
        flags.manual.assign(pings.range_counts.size(), 0);
        for (std::size_t j = 0; j < flags.cleaning.size(); j += 53) {
            flags.cleaning[j] = static_cast<std::uint8_t>(survey::SoundingStatus::kFreeSpace);
        }
        for (std::size_t j = 5; j < flags.manual.size(); j += 301) {
            flags.manual[j] = static_cast<std::uint8_t>(survey::ManualEdit::kReject);
        }
    }
};

GeorefPoints Join(const std::vector<GeorefPoints>& blocks) {
    GeorefPoints all;
    for (const GeorefPoints& b : blocks) AppendPoints(b, all);
    return all;
}

bool SameBits(const void* a, const void* b, std::size_t bytes) {
    return bytes == 0 || std::memcmp(a, b, bytes) == 0;
}

void ExpectSamePoints(const GeorefPoints& a, const GeorefPoints& b) {
    ASSERT_EQ(a.size(), b.size());
    EXPECT_EQ(a.ping, b.ping);
    EXPECT_EQ(a.beam, b.beam);
    EXPECT_EQ(a.status, b.status);
    EXPECT_TRUE(SameBits(
        a.position_world.data(), b.position_world.data(), a.size() * sizeof(Eigen::Vector3d)));
    EXPECT_TRUE(SameBits(a.range_m.data(), b.range_m.data(), a.size() * sizeof(float)));
    EXPECT_TRUE(SameBits(a.angle_rad.data(), b.angle_rad.data(), a.size() * sizeof(float)));
}

std::shared_ptr<const svp::Refraction> LayeredWater() {
    svp::SoundSpeedCast cast;
    cast.name = "layered";
    cast.depth_m = {0, 4, 8, 30};
    cast.speed_mps = {1495, 1480, 1470, 1468};
    return std::make_shared<const svp::Refraction>(std::vector<svp::SoundSpeedCast>{cast},
                                                   svp::CastSelection::kNearestPreceding,
                                                   svp::SurfaceSpeedSource::kProfile,
                                                   0.0);
}

TEST(GeorefBlocks, BlocksOfPingsGiveRunGeorefsViewBitForBit) {
    const BlockSurvey sv;
    survey::SonarMount mount;
    mount.lever_arm_m = Eigen::Vector3d(0.8, 0.1, 0.3);
    mount.boresight_roll_deg = 0.7;
    const GeorefConfig cfg;
    for (const auto& refraction : {std::shared_ptr<const svp::Refraction>(), LayeredWater()}) {
        for (const auto view : {survey::SoundingView::kAccepted,
                                survey::SoundingView::kRejected,
                                survey::SoundingView::kCandidates}) {
            const GeorefResult whole = RunGeoref(
                sv.nav, sv.pings, mount, cfg, std::nullopt, {}, refraction, &sv.flags, view);
            ASSERT_GT(whole.points.size(), 1000u);
            ASSERT_GT(whole.counts.pings_in_nav_gap + whole.counts.pings_outside_nav, 0);
            for (const std::size_t block :
                 {std::size_t{0}, std::size_t{121}, std::size_t{1000}, std::size_t{1} << 30}) {
                std::vector<GeorefPoints> blocks;
                std::size_t pings_seen = 0;
                const GeorefResult by = RunGeorefByBlocks(
                    sv.nav,
                    sv.pings,
                    mount,
                    cfg,
                    block,
                    [&](const GeorefPoints& b, const GeorefResult& so_far) {
                        // Whole pings, their indices into the pings so far.
                        for (std::uint32_t k : b.ping) EXPECT_LT(k, so_far.pings.size());
                        EXPECT_GE(so_far.pings.size(), pings_seen);
                        pings_seen = so_far.pings.size();
                        EXPECT_TRUE(so_far.points.size() == b.size());
                        blocks.push_back(b);
                        return true;
                    },
                    std::nullopt,
                    {},
                    refraction,
                    &sv.flags,
                    view);
                SCOPED_TRACE("block " + std::to_string(block));
                EXPECT_EQ(by.points.size(), 0u) << "the view is not held";
                if (block == 0) {
                    EXPECT_GE(blocks.size(), 250u);
                }
                ExpectSamePoints(Join(blocks), whole.points);
                ASSERT_EQ(by.pings.size(), whole.pings.size());
                for (std::size_t k = 0; k < by.pings.size(); ++k) {
                    EXPECT_EQ(by.pings[k].header_index, whole.pings[k].header_index);
                    EXPECT_EQ(by.pings[k].cast, whole.pings[k].cast);
                    EXPECT_TRUE(SameBits(
                        by.pings[k].sensor_world.data(), whole.pings[k].sensor_world.data(), 24));
                }
                EXPECT_EQ(by.counts.status, whole.counts.status);
                EXPECT_EQ(by.counts.points, whole.counts.points);
                EXPECT_EQ(by.counts.pings_georeferenced, whole.counts.pings_georeferenced);
                EXPECT_EQ(by.counts.pings_in_nav_gap, whole.counts.pings_in_nav_gap);
                EXPECT_EQ(by.counts.pings_outside_nav, whole.counts.pings_outside_nav);
                EXPECT_EQ(by.counts.spikes, whole.counts.spikes);
                EXPECT_EQ(by.message, whole.message);
            }
        }
    }
}

TEST(GeorefBlocks, ASinkThatFailsStopsTheGeoreference) {
    const BlockSurvey sv;
    int calls = 0;
    const GeorefResult r =
        RunGeorefByBlocks(sv.nav,
                          sv.pings,
                          survey::SonarMount{},
                          GeorefConfig{},
                          1000,
                          [&](const GeorefPoints&, const GeorefResult&) { return ++calls < 3; });
    EXPECT_EQ(calls, 3);
    EXPECT_TRUE(r.cancelled);
    EXPECT_FALSE(r.message.empty());
}

// Decision 041: a stage command's view made a block of pings at a time (GeoreferenceByBlocks,
// what LoadSurvey writes to the view's file) is the survey's view: RunGeoref's points moved onto
// the trajectory asked for (ApplyTrajectory), bit for bit, with the pings that version lacks
// left on the navigation and counted; and Georeference (now on blocks) is the same view held.
TEST(GeorefBlocks, TheSurveysViewByBlocksIsRunGeorefMovedOntoItsTrajectory) {
    const BlockSurvey sv;
    survey::SurveyModel m;
    m.ingest.nav = sv.nav;
    m.ingest.pings = sv.pings;
    m.flags = sv.flags;
    m.mount.lever_arm_m = Eigen::Vector3d(0.8, 0.1, 0.3);
    m.origin = {40.0005, -7.0003, 95.0};
    const GeorefConfig cfg;
    const GeorefResult ins =
        RunGeoref(sv.nav, sv.pings, m.mount, cfg, m.origin, {}, nullptr, &sv.flags);
    const std::size_t num_pings = sv.pings.pings.size();
    m.trajectory(survey::TrajectoryVersion::kIns) = TrajectoryOf(ins, num_pings);
    // SLAM's trajectory: every pose moved a little (a rotation and a shift growing along the
    // survey); a few pings it has no pose for.
    survey::PingTrajectory slam = m.trajectory(survey::TrajectoryVersion::kIns);
    for (std::size_t i = 0; i < num_pings; ++i) {
        const double f = static_cast<double>(i) / static_cast<double>(num_pings);
        Pose d = Pose::Identity();
        d.linear() = Eigen::AngleAxisd(0.002 * f, Eigen::Vector3d::UnitZ()).toRotationMatrix();
        d.translation() = Eigen::Vector3d(0.3 * f, -0.1, 0.05 * std::sin(7.0 * f));
        slam.T_world_vehicle[i] = d * slam.T_world_vehicle[i];
        if (i % 37 == 5) slam.valid[i] = 0;
    }
    for (const bool with_slam : {false, true}) {
        SCOPED_TRACE(with_slam ? "on SLAM's trajectory" : "on the INS's");
        if (with_slam) m.trajectory(survey::TrajectoryVersion::kSlam) = slam;
        GeorefResult expected = ins;
        const std::size_t expected_kept = with_slam ? ApplyTrajectory(expected, slam) : 0;
        ASSERT_GT(expected.points.size(), 1000u);
        std::vector<GeorefPoints> blocks;
        std::size_t kept = 99;
        const GeorefResult by = GeoreferenceByBlocks(
            m,
            m.latest(),
            cfg,
            nullptr,
            1000,
            [&](const GeorefPoints& b, const GeorefResult&) {
                blocks.push_back(b);
                return true;
            },
            {},
            &kept);
        EXPECT_GT(blocks.size(), 10u);
        EXPECT_EQ(by.points.size(), 0u) << "the view is not held";
        ExpectSamePoints(Join(blocks), expected.points);
        EXPECT_EQ(kept, expected_kept);
        if (with_slam) {
            EXPECT_GT(kept, 0u);
        }
        ASSERT_EQ(by.pings.size(), expected.pings.size());
        for (std::size_t k = 0; k < by.pings.size(); ++k) {
            EXPECT_TRUE(SameBits(by.pings[k].T_world_vehicle.data(),
                                 expected.pings[k].T_world_vehicle.data(),
                                 sizeof(Pose)));
        }
        std::size_t held_kept = 99;
        const GeorefResult held = Georeference(m, m.latest(), cfg, nullptr, {}, &held_kept);
        ExpectSamePoints(held.points, expected.points);
        EXPECT_EQ(held_kept, expected_kept);
    }
}

TEST(GeorefBlocks, TheNewMountOnBlocksIsRegeoreferencesBitForBit) {
    const BlockSurvey sv;
    survey::SonarMount mount;
    mount.lever_arm_m = Eigen::Vector3d(0.8, 0.1, 0.3);
    survey::SonarMount calibrated = mount;
    calibrated.boresight_roll_deg = 0.31;
    calibrated.boresight_pitch_deg = -0.2;
    calibrated.boresight_yaw_deg = 0.9;
    for (const auto& refraction : {std::shared_ptr<const svp::Refraction>(), LayeredWater()}) {
        GeorefResult whole = RunGeoref(
            sv.nav, sv.pings, mount, GeorefConfig{}, std::nullopt, {}, refraction, &sv.flags);
        GeorefResult by = whole;
        Regeoreference(whole, calibrated);
        const Remount remount(by, calibrated);
        std::vector<GeorefPoints> blocks;
        for (std::size_t first = 0; first < by.points.size(); first += 777) {
            GeorefPoints b =
                SliceOf(by.points, first, std::min(by.points.size(), first + 777) - first);
            remount.Apply(b);
            blocks.push_back(std::move(b));
        }
        ExpectSamePoints(Join(blocks), whole.points);
        ASSERT_EQ(by.pings.size(), whole.pings.size());
        for (std::size_t k = 0; k < by.pings.size(); ++k) {
            EXPECT_TRUE(
                SameBits(by.pings[k].sensor_world.data(), whole.pings[k].sensor_world.data(), 24));
        }
        EXPECT_EQ(by.mount.boresight_yaw_deg, calibrated.boresight_yaw_deg);
    }
}

}  // namespace
}  // namespace pitmap::proc::georef
