// SPDX-License-Identifier: MIT
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <thread>
#include <vector>

#include "common/frames.hpp"
#include "tools/sim/nav_errors.hpp"
#include "tools/sim/trajectory.hpp"
#include "tools/sim/world.hpp"

namespace pitmap::sim {
namespace {

TEST(SurveyTrack, EveryScenarioTrackFloatsAndIsLongEnough) {
    for (const auto& name : BuiltinScenarioNames()) {
        const ScenarioConfig sc = *BuiltinScenario(name);
        const PitWorld world(sc.pit, sc.seed);
        auto track = SurveyTrack::Plan(sc);
        ASSERT_TRUE(track.ok()) << name;
        EXPECT_GE(track->length_m(), sc.track.duration_s * sc.track.speed_mps) << name;
        double min_depth = 1e9;
        for (const auto& p : track->points())
            min_depth = std::min(min_depth, world.Depth(p.x(), p.y()));
        EXPECT_GT(min_depth, 1.0) << name << ": the boat would run aground";
    }
}

// Number of crossings of the track with itself (segments 1 m apart, neighbours along the track
// within `skip_m` not compared), and the positions where it crosses.
std::vector<Eigen::Vector2d> SelfCrossings(const SurveyTrack& track, double skip_m) {
    std::vector<Eigen::Vector2d> p;
    for (double s = 0; s < track.length_m(); s += 1.0) p.push_back(track.PositionAt(s));
    std::vector<Eigen::Vector2d> out;
    const auto cross = [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
        return a.x() * b.y() - a.y() * b.x();
    };
    const auto skip = static_cast<std::size_t>(skip_m);
    for (std::size_t i = 0; i + 1 < p.size(); ++i) {
        for (std::size_t j = i + skip; j + 1 < p.size(); ++j) {
            const Eigen::Vector2d r = p[i + 1] - p[i], q = p[j + 1] - p[j];
            const double den = cross(r, q);
            if (std::abs(den) < 1e-9) continue;
            const double t = cross(p[j] - p[i], q) / den, u = cross(p[j] - p[i], r) / den;
            if (t >= 0 && t < 1 && u >= 0 && u < 1) out.push_back(p[i] + t * r);
        }
    }
    return out;
}

TEST(SurveyTrack, StarAndZigzagLinesFloatAndCross) {
    for (const TrackPattern pattern : {TrackPattern::kStar, TrackPattern::kZigzag}) {
        for (const char* name : {"quarry", "demo", "bejanca"}) {
            ScenarioConfig sc = *BuiltinScenario(name);
            sc.track.pattern = pattern;
            sc.track.duration_s = 300;
            const PitWorld world(sc.pit, sc.seed);
            auto track = SurveyTrack::Plan(sc);
            ASSERT_TRUE(track.ok()) << name;
            EXPECT_GE(track->length_m(), sc.track.duration_s * sc.track.speed_mps) << name;
            double min_depth = 1e9, min_shore = 1e9;
            for (const auto& p : track->points()) {
                min_depth = std::min(min_depth, world.Depth(p.x(), p.y()));
                min_shore = std::min(min_shore, DistanceFromShore(sc.pit, p.x(), p.y()));
            }
            EXPECT_GT(min_depth, 1.0) << name << " " << ToString(pattern);
            EXPECT_GT(min_shore, 0.5 * sc.track.first_lap_offset_m) << name;
        }
    }
    // The star: one pattern's lines all pass the pit centre, every 180 / n deg of heading.
    ScenarioConfig sc = *BuiltinScenario("quarry");
    sc.track.pattern = TrackPattern::kStar;
    sc.track.duration_s = 0;  // one pattern
    auto star = SurveyTrack::Plan(sc);
    ASSERT_TRUE(star.ok());
    std::vector<double> headings_deg;  // of the passes through the centre, mod 180
    bool near = false;
    for (double s = 0; s < star->length_m(); s += 0.1) {
        const bool now = star->PositionAt(s).norm() < 0.5;
        if (now && !near) {
            headings_deg.push_back(std::fmod(frames::RadToDeg(star->HeadingAt(s)) + 360.0, 180.0));
        }
        near = now;
    }
    ASSERT_EQ(static_cast<int>(headings_deg.size()), sc.track.star_lines);
    std::sort(headings_deg.begin(), headings_deg.end());
    for (std::size_t k = 0; k < headings_deg.size(); ++k) {
        const double next =
            k + 1 < headings_deg.size() ? headings_deg[k + 1] : headings_deg[0] + 180;
        EXPECT_NEAR(next - headings_deg[k], 180.0 / sc.track.star_lines, 2.0) << k;
    }
    // The zigzag: the way back crosses every leg of the way out (legs - 1 crossings at least,
    // away from the turning points), and laps of one pattern do not cross at all but for the
    // tie line's.
    sc.track.pattern = TrackPattern::kZigzag;
    auto zigzag = SurveyTrack::Plan(sc);
    ASSERT_TRUE(zigzag.ok());
    EXPECT_GE(static_cast<int>(SelfCrossings(*zigzag, 10.0).size()), sc.track.zigzag_legs - 1);
    sc.track.pattern = TrackPattern::kLaps;
    auto laps = SurveyTrack::Plan(sc);
    ASSERT_TRUE(laps.ok());
    EXPECT_LE(SelfCrossings(*laps, 10.0).size(), 4U);
}

TEST(SurveyTrack, PatternNames) {
    for (const TrackPattern p : {TrackPattern::kLaps, TrackPattern::kStar, TrackPattern::kZigzag}) {
        auto back = TrackPatternFromString(ToString(p));
        ASSERT_TRUE(back.ok());
        EXPECT_EQ(*back, p);
    }
    auto bad = TrackPatternFromString("spiral");
    ASSERT_FALSE(bad.ok());
    EXPECT_NE(bad.error().message.find("laps, star, zigzag"), std::string::npos);
    ScenarioConfig sc = *BuiltinScenario("quarry");
    sc.track.star_lines = 1;
    sc.track.zigzag_legs = 0;
    EXPECT_EQ(sc.Validate().size(), 2U);
}

TEST(SurveyTrack, HeadingIsSmooth) {
    ScenarioConfig sc = *BuiltinScenario("bejanca");
    for (const TrackPattern pattern :
         {TrackPattern::kLaps, TrackPattern::kStar, TrackPattern::kZigzag}) {
        sc.track.pattern = pattern;
        auto track = SurveyTrack::Plan(sc);
        ASSERT_TRUE(track.ok());
        double worst = 0;
        for (double s = 1; s < track->length_m() - 2; s += 0.5) {
            worst = std::max(
                worst, std::abs(frames::WrapPi(track->HeadingAt(s + 0.5) - track->HeadingAt(s))));
        }
        // The twin hull pivots in tight turns (the sharpest is the U-turn where the pattern
        // repeats, or a star line's end), but the track never kinks: over 0.5 m of travel the
        // heading changes by less than 60 deg (turn radius > 0.48 m) everywhere.
        EXPECT_LT(frames::RadToDeg(worst), 60.0) << ToString(pattern);
    }
}

TEST(TruthTrajectory, SpeedRatesAndDuration) {
    const ScenarioConfig sc = *BuiltinScenario("demo");
    TruthTrajectory truth(sc, *SurveyTrack::Plan(sc));
    EXPECT_NEAR(truth.duration_s(), 120.0, 1e-9);
    for (double t = 5; t < 115; t += 10) {
        const TruthState st = truth.StateAt(t);
        const double v = st.velocity_world.head<2>().norm();
        EXPECT_NEAR(v, sc.track.speed_mps, 0.15) << t;
        // Rates integrate to the pose change over 2 ms (error ~ angular acceleration * dt^2 / 2).
        const Pose later = truth.PoseAt(t + 0.002);
        const Eigen::Matrix3d predicted =
            st.T_world_vehicle.linear() * ExpSO3(st.angular_rate_vehicle * 0.002);
        EXPECT_LT(RotationAngleBetween(predicted, later.linear()), 1e-5) << t;
        // Wave motion stays within its amplitudes.
        const auto rpy = frames::RpyFromRotationWorld(st.T_world_vehicle.linear());
        EXPECT_LE(std::abs(frames::RadToDeg(rpy.roll)), sc.track.roll_amplitude_deg + 1e-9);
        EXPECT_LE(std::abs(st.T_world_vehicle.translation().z()),
                  sc.track.heave_amplitude_m + 1e-9);
    }
}

TEST(NavErrorModel, RtkQualityWithoutOutage) {
    NavErrorConfig cfg;
    NavErrorModel m(cfg, 1300, 42);
    double sum2 = 0;
    int n = 0;
    for (double t = 0; t < 1300; t += 1.0) {
        const NavError e = m.At(t);
        EXPECT_TRUE(e.gnss_available);
        sum2 += e.position_enu_m.head<2>().squaredNorm() / 2;
        ++n;
    }
    const double rms = std::sqrt(sum2 / n);
    EXPECT_GT(rms, 0.3 * cfg.position_gm_sigma_m);
    EXPECT_LT(rms, 3.0 * cfg.position_gm_sigma_m);
}

TEST(NavErrorModel, OutageDriftsSeveralMetresThenRecovers) {
    const ScenarioConfig sc = *BuiltinScenario("gps-outage");
    NavErrorModel m(sc.nav, sc.track.duration_s, sc.seed);
    const double start = sc.nav.outages_s[0], end = sc.nav.outages_s[1];
    double worst = 0;
    for (double t = start; t < end; t += 1.0) {
        EXPECT_FALSE(m.At(t).gnss_available);
        worst = std::max(worst, m.At(t).position_enu_m.norm());
    }
    EXPECT_GT(worst, 1.5);                                    // several metres of drift...
    EXPECT_LT(worst, 20.0);                                   // ...not kilometres
    EXPECT_GT(m.At(end - 1).position_stddev_enu_m.x(), 0.5);  // the INS admits it
    EXPECT_LT(m.At(end + 3 * sc.nav.recovery_time_s).position_enu_m.norm(), 0.2);
    // Same seed, same errors.
    NavErrorModel m2(sc.nav, sc.track.duration_s, sc.seed);
    EXPECT_EQ(m.At(300.0).position_enu_m, m2.At(300.0).position_enu_m);
}

// The model keeps a window of its error series (hours-long surveys): answers do not depend on
// the order of the queries, forward across many windows, backward before the window (it
// regenerates from the seed) or from several threads.
TEST(NavErrorModel, AnswersDoNotDependOnTheOrderOfTheQueries) {
    const ScenarioConfig sc = *BuiltinScenario("gps-outage");
    const double duration = 900.0;  // > 5 windows of NavErrorModel::kChunkSteps
    NavErrorModel forward(sc.nav, duration, sc.seed);
    std::vector<double> times;
    for (double t = 0; t <= duration + 5; t += 0.37) times.push_back(t);
    std::vector<NavError> expected;
    for (double t : times) expected.push_back(forward.At(t));

    NavErrorModel shuffled(sc.nav, duration, sc.seed);
    std::vector<std::size_t> order(times.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::mt19937 rng(5);
    std::shuffle(order.begin(), order.end(), rng);
    order.resize(300);  // each a jump, most of them backwards past the window
    for (std::size_t i : order) {
        const NavError e = shuffled.At(times[i]);
        EXPECT_EQ(e.position_enu_m, expected[i].position_enu_m) << times[i];
        EXPECT_EQ(e.attitude_rpy_rad, expected[i].attitude_rpy_rad) << times[i];
        EXPECT_EQ(e.position_stddev_enu_m, expected[i].position_stddev_enu_m) << times[i];
    }
    // Two threads reading forward at once (the HIL rig's emulator and a test).
    NavErrorModel shared(sc.nav, duration, sc.seed);
    std::vector<int> mismatches(2, 0);
    std::vector<std::thread> threads;
    for (int k = 0; k < 2; ++k) {
        threads.emplace_back([&, k] {
            for (std::size_t i = static_cast<std::size_t>(k); i < times.size(); i += 2) {
                if (shared.At(times[i]).position_enu_m != expected[i].position_enu_m)
                    ++mismatches[static_cast<std::size_t>(k)];
            }
        });
    }
    for (auto& th : threads) th.join();
    EXPECT_EQ(mismatches[0] + mismatches[1], 0);
}

}  // namespace
}  // namespace pitmap::sim
