// SPDX-License-Identifier: MIT
// What ingest checks the merged inputs for (processor/io/ingest_sessions.hpp), on series built
// here: repeated messages against two recordings at one time, sessions separated by a gap or a
// jump (an error naming the files, or one picked by ingest.session), the INS status rule with
// its windows and sigma floors, and the gaps within a session.
#include "processor/io/ingest_sessions.hpp"

#include <gtest/gtest.h>

#include <string>

#include "processor/survey/series.hpp"

namespace pitmap::proc::io::detail {
namespace {

using survey::NavSample;
using survey::NavStdDev;
using survey::PingHeader;

constexpr std::int64_t kT0 = 1'400'000'000'000'000;  // 2024, GPS microseconds

bool Contains(const std::string& text, const std::string& what) {
    return text.find(what) != std::string::npos;
}

// `n` INS samples at 50 Hz from t0 moving north at 1.5 m/s, status `status`, read from `path`.
void AddNav(IngestResult& r,
            const std::string& path,
            std::int64_t t0,
            int n,
            double lat0,
            std::int32_t status = 3) {
    const SpanMark mark = MarkSpan(r);
    for (int i = 0; i < n; ++i) {
        NavSample s;
        s.utime_gps = t0 + static_cast<std::int64_t>(i) * 20'000;
        s.position = {lat0 + i * 0.03 / 111000.0, -7.78, 412.0};
        s.ins_status = status;
        r.nav.samples.push_back(s);
        if (i % 50 == 0)
            r.nav.stddevs.push_back({s.utime_gps, 0.01f, 0.01f, 0.015f, 0.01f, 0.01f, 0.03f});
    }
    RecordSpan(r, path, mark);
}

void AddPings(
    IngestResult& r, const std::string& path, std::int64_t t0, int n, std::int32_t range) {
    const SpanMark mark = MarkSpan(r);
    for (int i = 0; i < n; ++i) {
        PingHeader h;
        h.utime_gps = t0 + static_cast<std::int64_t>(i) * 100'000;
        h.ping_number = i;
        h.beam_offset = static_cast<std::uint32_t>(r.pings.range_counts.size());
        h.num_beams = 4;
        r.pings.pings.push_back(h);
        for (int b = 0; b < 4; ++b) r.pings.range_counts.push_back(range + b);
    }
    RecordSpan(r, path, mark);
}

TEST(IngestSessions, ARepeatedMessageIsADuplicateAndTwoRecordingsAreAConflict) {
    IngestResult same;
    AddNav(same, "a.lcmlog", kT0, 500, 40.44);
    AddNav(same, "a_copy.lcmlog", kT0, 500, 40.44);
    std::vector<std::int64_t> conflicts;
    survey::SortAndDeduplicate(same.nav, &conflicts);
    EXPECT_EQ(same.nav.samples.size(), 500u);
    EXPECT_TRUE(conflicts.empty());

    IngestResult two;
    AddNav(two, "a.lcmlog", kT0, 500, 40.44);
    AddNav(two, "b.lcmlog", kT0, 500, 40.45);  // 1.1 km away, same times
    AddPings(two, "a.lcmlog", kT0, 100, 4000);
    AddPings(two, "b.lcmlog", kT0, 100, 5000);
    std::vector<std::int64_t> nav_c, ping_c;
    survey::SortAndDeduplicate(two.nav, &nav_c);
    survey::SortAndDeduplicate(two.pings, &ping_c);
    EXPECT_EQ(nav_c.size(), 500u);
    EXPECT_EQ(ping_c.size(), 100u);
    two.conflict_times = nav_c;
    two.counts.nav_conflicts = 500;
    two.counts.ping_conflicts = 100;
    const Status s = CheckConflicts(two);
    ASSERT_FALSE(s);
    EXPECT_TRUE(Contains(s.error().message, "held twice with different content"))
        << s.error().message;
    EXPECT_TRUE(Contains(s.error().message, "a.lcmlog, b.lcmlog")) << s.error().message;
}

TEST(IngestSessions, ADayApartIsTwoRecordingsNamedWithTheirFiles) {
    IngestResult r;
    AddNav(r, "monday.lcmlog", kT0, 1000, 40.44);
    AddPings(r, "monday.lcmlog", kT0, 150, 4000);
    AddNav(r, "tuesday.lcmlog", kT0 + 86'400'000'000, 1000, 40.44);
    AddPings(r, "tuesday.lcmlog", kT0 + 86'400'000'000, 150, 4000);
    IngestConfig c;
    IngestResult copy = r;
    const Status s = SplitSessions(copy, c);
    ASSERT_FALSE(s);
    const std::string& m = s.error().message;
    EXPECT_TRUE(Contains(m, "the inputs hold 2 recordings")) << m;
    EXPECT_TRUE(Contains(m, "1.0 days later")) << m;
    EXPECT_TRUE(Contains(m, "from monday.lcmlog")) << m;
    EXPECT_TRUE(Contains(m, "from tuesday.lcmlog")) << m;
    EXPECT_TRUE(Contains(m, "ingest.session")) << m;
    // Picked: only the second, said.
    c.session = 2;
    ASSERT_TRUE(SplitSessions(r, c));
    EXPECT_EQ(r.nav.samples.size(), 1000u);
    EXPECT_EQ(r.nav.samples.front().utime_gps, kT0 + 86'400'000'000);
    EXPECT_EQ(r.pings.pings.size(), 150u);
    EXPECT_EQ(r.pings.pings.front().beam_offset, 0u);
    EXPECT_EQ(r.pings.range_counts.size(), 600u);
    EXPECT_TRUE(Contains(r.warnings.back(), "ingest.session 2 of 2 recordings kept"));
}

TEST(IngestSessions, AJumpNoVehicleMakesIsTwoRecordings) {
    IngestResult r;
    AddNav(r, "pit_a.lcmlog", kT0, 1000, 40.44);
    AddNav(r, "pit_b.lcmlog", kT0 + 20'000'000 + 60'000'000, 1000, 40.49);  // 5.5 km, 1 min
    const Status s = SplitSessions(r, IngestConfig{});
    ASSERT_FALSE(s);
    EXPECT_TRUE(Contains(s.error().message, "km away")) << s.error().message;
    // One survey with a 30 s pause is one recording, its gap reported.
    IngestResult one;
    AddNav(one, "x.lcmlog", kT0, 1000, 40.44);
    AddNav(one, "y.lcmlog", kT0 + 50'000'000, 1000, 40.44 + 1000 * 0.03 / 111000.0);
    ASSERT_TRUE(SplitSessions(one, IngestConfig{}));
    EXPECT_EQ(one.counts.sessions, 1);
    ReportGaps(one, IngestConfig{});
    EXPECT_EQ(one.counts.nav_gaps, 1);
    EXPECT_TRUE(
        Contains(one.warnings.back(), "1 gap(s) over 2.0 s in the navigation: 30.0 s after"))
        << one.warnings.back();
}

TEST(IngestSessions, InsStatusWindowsAreDroppedOrDownWeightedAndListed) {
    IngestResult r;
    AddNav(r, "a.lcmlog", kT0, 500, 40.44);                  // good
    AddNav(r, "a.lcmlog", kT0 + 10'000'000, 500, 40.44, 1);  // ALIGNING 10 s
    AddNav(r, "a.lcmlog", kT0 + 20'000'000, 500, 40.44, 2);  // HIGH_VARIANCE 10 s
    AddNav(r, "a.lcmlog", kT0 + 30'000'000, 500, 40.44);
    IngestConfig c;
    IngestResult keep = r;
    ApplyInsStatusRule(keep, c);
    ASSERT_EQ(keep.ins_windows.size(), 2u);
    EXPECT_FALSE(keep.ins_windows[0].navigating);
    EXPECT_TRUE(keep.ins_windows[0].dropped);
    EXPECT_EQ(keep.ins_windows[0].statuses, "INS_ALIGNING");
    EXPECT_TRUE(keep.ins_windows[1].navigating);
    EXPECT_FALSE(keep.ins_windows[1].dropped);
    EXPECT_EQ(keep.counts.nav_not_navigating, 500);
    EXPECT_EQ(keep.counts.nav_degraded, 500);
    EXPECT_EQ(keep.counts.nav_not_good, 500);  // dropped for its status
    EXPECT_EQ(keep.nav.samples.size(), 1500u);
    // The degraded window's sigmas are raised to the floors; the good ones are not.
    for (const NavStdDev& s : keep.nav.stddevs) {
        const bool in = s.utime_gps >= kT0 + 20'000'000 && s.utime_gps < kT0 + 30'000'000;
        EXPECT_EQ(s.north_m >= 0.5f, in) << s.utime_gps;
        if (in) {
            EXPECT_GE(s.yaw_deg, 0.2f);
        }
    }
    EXPECT_TRUE(Contains(keep.warnings[0], "INS status INS_ALIGNING")) << keep.warnings[0];
    EXPECT_TRUE(Contains(keep.warnings[1], "kept with its sigmas raised")) << keep.warnings[1];
    // require_good_ins drops the degraded window too.
    c.require_good_ins = true;
    ApplyInsStatusRule(r, c);
    EXPECT_EQ(r.nav.samples.size(), 1000u);
    EXPECT_EQ(r.counts.nav_not_good, 1000);
}

}  // namespace
}  // namespace pitmap::proc::io::detail
