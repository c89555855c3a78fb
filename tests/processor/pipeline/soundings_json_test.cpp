// SPDX-License-Identifier: MIT
// summary.json's "soundings" (SoundingsJson) from georef's counts: the soundings per status, and
// the pings georef could not place, by reason, with their beams, so that no ping leaves the
// products unsaid (issue 35: the quarry's first ping, moved before the navigation by the
// latency correction, was left out silently).
#include <gtest/gtest.h>

#include "common/frames.hpp"
#include "processor/georef/georef.hpp"
#include "processor/pipeline/internal.hpp"

namespace pitmap::proc::pipeline::detail {
namespace {

constexpr int kBeams = 21;

// A level vehicle heading north, INS at 50 Hz from t0 for n samples.
survey::NavSeries Nav(std::int64_t t0, int n) {
    survey::NavSeries nav;
    const LocalTangentFrame world({40.0, -7.0, 100.0});
    for (int i = 0; i < n; ++i) {
        survey::NavSample s;
        s.utime_gps = t0 + i * 20'000;
        s.position = world.FromEnu(Eigen::Vector3d(0, 0.1 * i, 0));
        nav.samples.push_back(s);
    }
    return nav;
}

// A ping over a flat bottom 10 m down; beam 3 has no detection.
void AddPing(survey::PingSeries& s, std::int64_t t) {
    survey::PingHeader h;
    h.utime_gps = t;
    h.range_resolution_m = 0.001;
    h.start_angle_deg = -20;
    h.angle_increment_deg = 2.0;
    h.beam_offset = static_cast<std::uint32_t>(s.range_counts.size());
    h.num_beams = kBeams;
    for (int i = 0; i < kBeams; ++i) {
        const double th = frames::DegToRad(h.start_angle_deg + i * h.angle_increment_deg);
        s.range_counts.push_back(
            i == 3 ? 0u : static_cast<std::uint32_t>(std::lround(10.0 / std::cos(th) / 0.001)));
    }
    s.pings.push_back(h);
}

TEST(SoundingsJson, SaysWhichPingsWereLeftOutAndWhy) {
    // INS over [1.0, 1.18] s and [3.0, 3.18] s.
    survey::NavSeries nav = Nav(1'000'000, 10);
    const survey::NavSeries later = Nav(3'000'000, 10);
    nav.samples.insert(nav.samples.end(), later.samples.begin(), later.samples.end());
    survey::PingSeries pings;
    AddPing(pings, 1'000'000 - 1'300);  // 1.3 ms early: placed by extrapolation
    AddPing(pings, 1'100'000);          // inside
    AddPing(pings, 2'000'000);          // in the gap
    AddPing(pings, 500'000);            // long before the navigation
    AddPing(pings, 3'100'000);          // inside
    const georef::GeorefResult r =
        georef::RunGeoref(nav, pings, survey::SonarMount{}, georef::GeorefConfig{});
    const nlohmann::json j = SoundingsJson(r.counts);
    EXPECT_EQ(j["pings"]["in"], 5);
    EXPECT_EQ(j["pings"]["georeferenced"], 3);
    EXPECT_EQ(j["pings"]["left_out"]["outside_nav"], 1);
    EXPECT_EQ(j["pings"]["left_out"]["nav_gap"], 1);
    EXPECT_EQ(j["pings"]["left_out"]["bad_header"], 0);
    // The soundings of the placed pings by status; the left-out pings' beams apart.
    EXPECT_EQ(j["total"], 3 * kBeams);
    EXPECT_EQ(j["accepted"], 3 * (kBeams - 1));
    EXPECT_EQ(j["rejected"]["no_detection"], 3);
    EXPECT_EQ(j["not_placed"], 2 * kBeams);

    // Without the extrapolation the first ping is left out too, and said.
    georef::GeorefConfig within_span;
    within_span.max_nav_extrapolation_s = 0;
    const nlohmann::json k =
        SoundingsJson(georef::RunGeoref(nav, pings, survey::SonarMount{}, within_span).counts);
    EXPECT_EQ(k["pings"]["georeferenced"], 2);
    EXPECT_EQ(k["pings"]["left_out"]["outside_nav"], 2);
    EXPECT_EQ(k["not_placed"], 3 * kBeams);
}

}  // namespace
}  // namespace pitmap::proc::pipeline::detail
