// SPDX-License-Identifier: MIT
// The coarse sonar clock (header position, header attitude, span) and the latency found jointly
// with the boresight, on a synthetic survey whose sonar clock is off by a known amount.
#include "processor/calib/sonar_clock.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "processor/calib/boresight.hpp"
#include "synthetic_survey.hpp"

namespace pitmap::proc::calib {
namespace {

using testing::MakeSurvey;
using testing::SurveyOptions;

TEST(SonarClock, HeaderPositionFindsAnOffsetOfAnHour) {
    SurveyOptions o;
    o.clock_error_s = 3600.0 + 2.35;  // topside clock an hour and 2.35 s ahead
    o.header_position = true;
    const auto sv = MakeSurvey(o);
    const ClockEstimate e = EstimateSonarClock(sv.pings, sv.nav);
    ASSERT_TRUE(e.found) << e.message;
    EXPECT_EQ(e.method, "header position");
    // The fixes are 0.15-0.25 s old; 0.15 s on average is taken off, the rest is in sigma.
    EXPECT_NEAR(e.correction_s, -o.clock_error_s, 0.1) << e.message;
    EXPECT_LE(std::abs(e.correction_s + o.clock_error_s), 2 * e.sigma_s) << e.message;
    EXPECT_LT(e.misfit, 1.0);
}

TEST(SonarClock, HeaderPositionWorksForAClockBehindToo) {
    SurveyOptions o;
    o.clock_error_s = -5 * 3600.0 - 0.8;
    o.header_position = true;
    const auto sv = MakeSurvey(o);
    const ClockEstimate e = EstimateSonarClock(sv.pings, sv.nav);
    ASSERT_TRUE(e.found) << e.message;
    EXPECT_NEAR(e.correction_s, -o.clock_error_s, 0.1) << e.message;
}

TEST(SonarClock, HeaderHeadingPlacesAndRollPitchRefine) {
    SurveyOptions o;
    o.clock_error_s = -7.3;
    o.header_attitude = true;
    const auto sv = MakeSurvey(o);
    const ClockEstimate e = EstimateSonarClock(sv.pings, sv.nav);
    ASSERT_TRUE(e.found) << e.message;
    EXPECT_EQ(e.method, "header attitude");
    EXPECT_NEAR(e.correction_s, 7.3, 0.03) << e.message;
}

TEST(SonarClock, PeriodicRollAloneIsAmbiguousAndSaysSo) {
    SurveyOptions o;
    o.clock_error_s = 12.0;
    o.header_attitude = true;
    o.pitch_amplitude_deg = 0;  // one wave period: roll repeats every 3.5 s
    auto sv = MakeSurvey(o);
    for (auto& h : sv.pings.pings) h.aid_heading_deg = std::nan("");
    const ClockEstimate e = EstimateSonarClock(sv.pings, sv.nav);
    EXPECT_FALSE(e.found) << e.message;
    EXPECT_NE(e.message.find("ambiguous"), std::string::npos) << e.message;
}

TEST(SonarClock, NoAidsCentresTheSpansAndStatesTheUncertainty) {
    SurveyOptions o;
    o.clock_error_s = 40.0;
    const auto sv = MakeSurvey(o);
    const ClockEstimate same = EstimateSonarClock(sv.pings, sv.nav);
    ASSERT_TRUE(same.found) << same.message;
    EXPECT_EQ(same.method, "span");
    EXPECT_NEAR(same.correction_s, -40.0, 0.1) << same.message;
    EXPECT_LT(same.sigma_s, 0.1);
    // The sonar file stops 30 s before the navigation log: centring is 15 s off, and says
    // that it can be (sigma of a uniform 30 s).
    survey::PingSeries shorter = sv.pings;
    shorter.pings.resize(shorter.pings.size() - 300);
    const ClockEstimate e = EstimateSonarClock(shorter, sv.nav);
    EXPECT_NEAR(e.sigma_s, 30.0 / (2 * std::sqrt(3.0)), 0.2) << e.message;
    EXPECT_LE(std::abs(e.correction_s + 40.0), 2 * e.sigma_s) << e.message;
}

TEST(SonarClock, ShiftKeepsOrder) {
    SurveyOptions o;
    o.duration_s = 5;
    auto sv = MakeSurvey(o);
    const auto t0 = sv.pings.pings.front().utime_gps;
    survey::ShiftPingTimes(sv.pings, -1.25);
    EXPECT_EQ(sv.pings.pings.front().utime_gps, t0 - 1'250'000);
    EXPECT_EQ(SpanText(0, 2'500'000), "0.000 .. 2.500 GPS s (2.5 s)");
}

TEST(SonarClock, ALineShiftAddsTheRateFromTheReference) {
    SurveyOptions o;
    o.duration_s = 50;
    o.num_beams = 3;
    auto sv = MakeSurvey(o);
    const survey::PingSeries before = sv.pings;
    const std::int64_t ref = sv.pings.pings[100].utime_gps;
    survey::ShiftPingTimes(sv.pings, 1.2345, -47e-6, ref);
    for (std::size_t i : {0, 100, 499}) {
        const auto t0 = before.pings[i].utime_gps;
        EXPECT_NEAR(static_cast<double>(sv.pings.pings[i].utime_gps - t0),
                    1.2345e6 - 47e-6 * static_cast<double>(t0 - ref),
                    0.5)
            << i;
    }
}

// A topside clock 40 ppm fast (16 ms over the survey): the head's attitude sensor, sampled at
// every ping on that clock, times it along the survey.
TEST(SonarClockRate, FortyPpmAreFoundFromTheHeadsAttitude) {
    SurveyOptions o;
    o.duration_s = 400;
    o.num_beams = 3;
    o.clock_error_s = 0.02;
    o.clock_rate_ppm = 40;
    o.header_attitude = true;
    const auto sv = MakeSurvey(o);
    const ClockRateEstimate e = EstimateSonarClockRate(sv.pings, sv.nav);
    ASSERT_TRUE(e.found) << e.message;
    // The correction is minus the clock's error: -40 ppm.
    EXPECT_NEAR(e.rate_ppm, -40.0, std::max(3 * e.rate_sigma_ppm, 1.0)) << e.message;
    EXPECT_LT(e.rate_sigma_ppm, 5.0) << e.message;
    const double t_mid = static_cast<double>(e.reference_utime - sv.t0_utime) * 1e-6;
    EXPECT_NEAR(e.offset_s, -(0.02 + 40e-6 * t_mid), 0.002) << e.message;
    EXPECT_EQ(e.samples, 4000);
}

// Through a mount rolled 25 deg (a side-looking head): the INS attitude is composed with it.
TEST(SonarClockRate, ATiltedMountIsComposedWithTheInsAttitude) {
    SurveyOptions o;
    o.duration_s = 400;
    o.num_beams = 3;
    o.clock_rate_ppm = -30;
    o.header_attitude = true;
    o.truth.boresight_roll_deg = 25;
    o.truth.boresight_yaw_deg = 2;
    const auto sv = MakeSurvey(o);
    ClockRateConfig cfg;
    cfg.R_vehicle_sonar = o.truth.R_vehicle_sonar();
    const ClockRateEstimate e = EstimateSonarClockRate(sv.pings, sv.nav, cfg);
    ASSERT_TRUE(e.found) << e.message;
    EXPECT_NEAR(e.rate_ppm, 30.0, std::max(3 * e.rate_sigma_ppm, 1.0)) << e.message;
}

TEST(SonarClockRate, WithoutTheHeadsOwnAttitudeItSaysWhy) {
    SurveyOptions o;
    o.duration_s = 100;
    o.num_beams = 3;
    o.header_position = true;
    const ClockRateEstimate none = EstimateSonarClockRate(MakeSurvey(o).pings, MakeSurvey(o).nav);
    EXPECT_FALSE(none.found);
    EXPECT_NE(none.message.find("carry the head's own attitude"), std::string::npos)
        << none.message;
    // An attitude that is not the INS's (a sensor on another head): too poor a fit to time.
    o.header_attitude = true;
    auto sv = MakeSurvey(o);
    for (std::size_t i = 0; i < sv.pings.pings.size(); ++i)
        sv.pings.pings[i].aid_roll_deg = 3.0 * std::sin(0.37 * static_cast<double>(i));
    const ClockRateEstimate wrong = EstimateSonarClockRate(sv.pings, sv.nav);
    EXPECT_FALSE(wrong.found) << wrong.message;
    EXPECT_NE(wrong.message.find("not used"), std::string::npos) << wrong.message;
}

// The sonar's stamps are late by `error`: the joint calibration finds the latency (and the
// boresight) from the soundings alone.
BoresightResult CalibrateWithClockError(double error, double scan_s, survey::SonarMount* truth) {
    SurveyOptions o;
    o.clock_error_s = error;
    o.num_beams = 61;
    o.truth.lever_arm_m = Eigen::Vector3d(0.8, 0.0, 0.25);
    o.truth.boresight_roll_deg = 0.5;
    o.truth.boresight_pitch_deg = -0.3;
    o.truth.boresight_yaw_deg = 1.0;
    *truth = o.truth;
    const auto sv = MakeSurvey(o);
    survey::SonarMount nominal;
    nominal.lever_arm_m = o.truth.lever_arm_m;
    const auto geo = georef::RunGeoref(sv.nav, sv.pings, nominal, georef::GeorefConfig{});
    BoresightConfig cfg;
    cfg.latency_scan_s = scan_s;
    return CalibrateBoresight(geo, sv.nav, nominal, cfg);
}

TEST(SonarLatency, ThirtyMillisecondsAreFoundWithTheBoresight) {
    survey::SonarMount truth;
    const BoresightResult r = CalibrateWithClockError(0.030, 0.0, &truth);
    ASSERT_TRUE(r.latency_estimated) << r.message;
    EXPECT_NEAR(r.latency_s, -0.030, 0.002) << r.message;
    EXPECT_NEAR(r.mount.boresight_roll_deg, truth.boresight_roll_deg, 0.02) << r.message;
    EXPECT_NEAR(r.mount.boresight_pitch_deg, truth.boresight_pitch_deg, 0.02) << r.message;
    EXPECT_NEAR(r.mount.boresight_yaw_deg, truth.boresight_yaw_deg, 0.02) << r.message;
    EXPECT_LT(r.after.rms_m, 2 * r.after.expected_rms_m) << r.message;
}

TEST(SonarLatency, HalfASecondNeedsTheScanAndIsFoundWithIt) {
    survey::SonarMount truth;
    const BoresightResult r = CalibrateWithClockError(-0.45, 1.0, &truth);
    ASSERT_TRUE(r.latency_estimated) << r.message;
    EXPECT_NEAR(r.latency_scan_best_s, 0.45, 0.1) << r.message;
    EXPECT_NEAR(r.latency_s, 0.45, 0.002) << r.message;
    EXPECT_NEAR(r.mount.boresight_roll_deg, truth.boresight_roll_deg, 0.02) << r.message;
}

TEST(SonarLatency, WithoutLatencyTheBoresightAbsorbsTheClockError) {
    // The reason for the fourth unknown: the same data with latency fixed at 0.
    SurveyOptions o;
    o.clock_error_s = 0.1;
    o.num_beams = 61;
    o.truth.lever_arm_m = Eigen::Vector3d(0.8, 0.0, 0.25);
    const auto sv = MakeSurvey(o);
    const auto geo = georef::RunGeoref(sv.nav, sv.pings, o.truth, georef::GeorefConfig{});
    BoresightConfig cfg;
    cfg.estimate_latency = false;
    const BoresightResult fixed = CalibrateBoresight(geo, sv.nav, o.truth, cfg);
    cfg.estimate_latency = true;
    const BoresightResult joint = CalibrateBoresight(geo, sv.nav, o.truth, cfg);
    EXPECT_GT(fixed.after.rms_m, 1.5 * joint.after.rms_m) << fixed.message << "\n" << joint.message;
    EXPECT_NEAR(joint.latency_s, -0.1, 0.002) << joint.message;
}

// Issue 34: a step of the topside clock. The pings from number 300 on carry header times 1 s
// ahead of their aids; the head's attitude against the INS tells the step (each side scanned on
// its own) from a pause, and the pings before it are put on the later clock.
TEST(SonarClockSteps, AStepIsFoundAtItsPingAndEachSideGetsItsOffset) {
    SurveyOptions o;
    o.duration_s = 120;
    o.num_beams = 3;
    o.header_attitude = true;
    auto sv = MakeSurvey(o);
    for (std::size_t k = 300; k < sv.pings.pings.size(); ++k)
        sv.pings.pings[k].utime_gps += 1'000'000;
    const ClockStepResult r = FindSonarClockSteps(sv.pings, sv.nav);
    ASSERT_EQ(r.steps.size(), 1u) << r.message;
    EXPECT_TRUE(r.steps[0].resolved) << r.message;
    EXPECT_EQ(r.steps[0].ping_index, 300u);
    EXPECT_EQ(r.steps[0].ping_number, sv.pings.pings[300].ping_number);
    EXPECT_NEAR(r.steps[0].step_s, 1.0, 0.02) << r.message;
    EXPECT_EQ(r.method, "header attitude");
    // After the shift every ping is on one clock: the later one (most pings), 1 s ahead.
    survey::PingSeries fixed = sv.pings;
    ApplyClockSteps(fixed, r);
    const auto t0 = MakeSurvey(o).pings;
    for (std::size_t k : {0u, 150u, 299u, 300u, 800u}) {
        EXPECT_NEAR(
            static_cast<double>(fixed.pings[k].utime_gps - t0.pings[k].utime_gps), 1e6, 0.03e6)
            << k;
    }
}

TEST(SonarClockSteps, APauseIsNotAStepAndTheHeaderPositionsTellItToo) {
    SurveyOptions o;
    o.duration_s = 150;
    o.num_beams = 3;
    o.header_position = true;
    auto sv = MakeSurvey(o);
    // Pinging paused for 1 s: the ping numbers go on, the times jump, the aids agree.
    sv.pings.pings.erase(sv.pings.pings.begin() + 600, sv.pings.pings.begin() + 610);
    for (std::size_t k = 600; k < sv.pings.pings.size(); ++k) sv.pings.pings[k].ping_number -= 10;
    const ClockStepResult pause = FindSonarClockSteps(sv.pings, sv.nav);
    EXPECT_EQ(pause.pauses, 1) << pause.message;
    EXPECT_TRUE(pause.segment_shift_s.empty()) << pause.message;
    for (const auto& st : pause.steps) EXPECT_FALSE(st.resolved) << pause.message;
    // The same jump with the aids 2 s off on one side: a step, found from the positions.
    auto stepped = MakeSurvey(o);
    for (std::size_t k = 600; k < stepped.pings.pings.size(); ++k)
        stepped.pings.pings[k].utime_gps += 2'000'000;
    const ClockStepResult step = FindSonarClockSteps(stepped.pings, stepped.nav);
    EXPECT_EQ(step.method, "header position");
    ASSERT_EQ(step.steps.size(), 1u) << step.message;
    EXPECT_TRUE(step.steps[0].resolved) << step.message;
    EXPECT_NEAR(step.steps[0].step_s, 2.0, 0.2) << step.message;
}

TEST(SonarClockSteps, AClockSetBackCannotBeOrderedAndSaysSo) {
    SurveyOptions o;
    o.duration_s = 60;
    o.num_beams = 3;
    o.header_attitude = true;
    auto sv = MakeSurvey(o);
    for (std::size_t k = 300; k < sv.pings.pings.size(); ++k)
        sv.pings.pings[k].utime_gps -= 1'050'000;
    survey::SortAndDeduplicate(sv.pings);
    const ClockStepResult r = FindSonarClockSteps(sv.pings, sv.nav);
    EXPECT_GT(r.backward, 0) << r.message;
    EXPECT_NE(r.message.find("set back"), std::string::npos) << r.message;
    // A reset of the ping numbers (a restarted sonar) is neither.
    auto reset = MakeSurvey(o);
    for (std::size_t k = 300; k < reset.pings.pings.size(); ++k)
        reset.pings.pings[k].ping_number = static_cast<std::int64_t>(k - 300);
    const ClockStepResult after_reset = FindSonarClockSteps(reset.pings, reset.nav);
    EXPECT_EQ(after_reset.backward, 0) << after_reset.message;
    EXPECT_TRUE(after_reset.steps.empty()) << after_reset.message;
    // A clean survey has neither steps nor pauses.
    const ClockStepResult clean = FindSonarClockSteps(MakeSurvey(o).pings, sv.nav);
    EXPECT_TRUE(clean.steps.empty()) << clean.message;
    EXPECT_EQ(clean.backward, 0);
}

// A .83P of another survey: its header positions are metres from this navigation at every
// offset, and the message says so before it says "ambiguous".
TEST(SonarClock, HeaderPositionsOfAnotherSurveyMatchNowhere) {
    SurveyOptions o;
    o.duration_s = 120;
    o.num_beams = 3;
    o.header_position = true;
    auto sv = MakeSurvey(o);
    for (auto& h : sv.pings.pings) {
        if (std::isfinite(h.aid_latitude_deg)) h.aid_latitude_deg += 0.0002;  // 22 m north
    }
    const ClockEstimate e = EstimateSonarClock(sv.pings, sv.nav);
    EXPECT_FALSE(e.found) << e.message;
    EXPECT_NE(e.message.find("match this navigation nowhere"), std::string::npos) << e.message;
    EXPECT_GT(HeaderPositionMisfit(sv.pings, sv.nav, 0.0), 15.0);
    const auto own = MakeSurvey(o);
    EXPECT_LT(HeaderPositionMisfit(own.pings, own.nav, 0.0), 1.0);
}

}  // namespace
}  // namespace pitmap::proc::calib
