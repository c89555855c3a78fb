// SPDX-License-Identifier: MIT
// The sonar clock stage of the pipeline (ClockSurvey) and its quality gates, on an in-memory
// survey whose sonar clock is off by a known amount: an unknown offset is found and applied; a
// configured one is checked against the headers (a disagreement is a gate with both numbers);
// navigation and sonar that do not overlap, or headers that cannot place the sonar, are errors
// naming both time spans.
#include <gtest/gtest.h>

#include "../calib/synthetic_survey.hpp"
#include "processor/pipeline/internal.hpp"

namespace pitmap::proc::pipeline::detail {
namespace {

using calib::testing::MakeSurvey;
using calib::testing::SurveyOptions;

StageContext FromSynthetic(double clock_error_s, bool header_position) {
    SurveyOptions o;
    o.duration_s = 120;
    o.num_beams = 11;
    o.clock_error_s = clock_error_s;
    o.header_position = header_position;
    auto sv = MakeSurvey(o);
    StageContext s;
    s.model.ingest.nav = std::move(sv.nav);
    s.model.ingest.pings = std::move(sv.pings);
    s.summary = nlohmann::json::object();
    return s;
}

struct Collect {
    std::vector<std::string> lines;
    Log log() {
        return [this](const std::string& m) { lines.push_back(m); };
    }
};

TEST(ClockStage, AnUnknownOffsetIsFoundAndApplied) {
    StageContext s = FromSynthetic(3600 + 2.35, true);
    const std::int64_t true_first = s.model.ingest.pings.pings.front().utime_gps - 3'602'350'000;
    Collect c;
    ASSERT_TRUE(ClockSurvey(s, PipelineConfig{}, c.log()));
    const auto& clk = s.summary["sonar_clock"];
    EXPECT_EQ(clk["coarse"]["method"], "header position");
    EXPECT_NEAR(clk["correction_s"].get<double>(), -3602.35, 0.3);
    EXPECT_NEAR((s.model.ingest.pings.pings.front().utime_gps - true_first) * 1e-6, 0.0, 0.3);
    EXPECT_FALSE(s.summary.contains("quality_gates"));
    // The survey model, which the later stages read, holds the same correction.
    EXPECT_DOUBLE_EQ(s.model.clock.correction_s(), clk["correction_s"].get<double>());
    EXPECT_DOUBLE_EQ(s.model.clock.sigma_s(), clk["sigma_s"].get<double>());
    EXPECT_FALSE(s.model.clock.configured);
}

TEST(ClockStage, AConfiguredOffsetThatDisagreesTripsAGateWithBothNumbers) {
    // The user's offset was applied by ingest but is 2 s off: the headers say so.
    StageContext s = FromSynthetic(2.0, true);
    PipelineConfig cfg;
    cfg.ingest.sonar_clock_offset_known = true;
    cfg.ingest.sonar_clock_offset_s = 0.5;
    Collect c;
    ASSERT_TRUE(ClockSurvey(s, cfg, c.log()));
    ASSERT_TRUE(s.summary.contains("quality_gates"));
    const auto& g = s.summary["quality_gates"][0];
    EXPECT_EQ(g["gate"], "sonar_clock_disagrees");
    const std::string m = g["message"];
    EXPECT_NE(m.find("+0.500"), std::string::npos) << m;
    // Implied (sonar clock minus UTC, subtracted by ingest): the pings are still 2 s late, so
    // 0.5 + 2.0 (the fixes' mean age taken off, the rest inside the stated sigma).
    EXPECT_NE(m.find("implies +2.5"), std::string::npos) << m;
    EXPECT_EQ(s.summary["sonar_clock"]["correction_s"].get<double>(), 0.0);  // kept
}

TEST(ClockStage, AConfiguredOffsetThatAgreesIsQuiet) {
    StageContext s = FromSynthetic(0.0, true);
    PipelineConfig cfg;
    cfg.ingest.sonar_clock_offset_known = true;
    Collect c;
    ASSERT_TRUE(ClockSurvey(s, cfg, c.log()));
    EXPECT_FALSE(s.summary.contains("quality_gates")) << s.summary.dump();
}

TEST(ClockStage, NoOverlapIsAnErrorNamingBothSpans) {
    // A daemon-stamped survey whose navigation ended before the sonar started.
    StageContext s = FromSynthetic(500.0, false);
    s.model.ingest.pings.clock = survey::PingClock::kGpsStamped;
    Collect c;
    const Status st = ClockSurvey(s, PipelineConfig{}, c.log());
    ASSERT_FALSE(st);
    EXPECT_NE(st.error().message.find("do not overlap"), std::string::npos);
    EXPECT_NE(st.error().message.find("navigation 1400000000.000 .. 1400000120.000 GPS s"),
              std::string::npos)
        << st.error().message;
    EXPECT_NE(st.error().message.find("sonar 1400000500.050"), std::string::npos)
        << st.error().message;
}

TEST(ClockStage, HeadersThatCannotPlaceTheSonarAreAnErrorAskingForTheOffset) {
    // No aids, and a sonar file much shorter than the navigation: the span is too uncertain.
    StageContext s = FromSynthetic(30.0, false);
    s.model.ingest.pings.pings.resize(300);  // 30 s of a 120 s navigation
    Collect c;
    const Status st = ClockSurvey(s, PipelineConfig{}, c.log());
    ASSERT_FALSE(st);
    EXPECT_NE(st.error().message.find("--sonar-clock-offset"), std::string::npos)
        << st.error().message;
    EXPECT_NE(st.error().message.find("max_clock_scan_s"), std::string::npos) << st.error().message;
}

}  // namespace
}  // namespace pitmap::proc::pipeline::detail
