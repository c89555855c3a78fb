// SPDX-License-Identifier: MIT
// Sound-velocity cast readers: CARIS .svp (several sections with time and position), CSV and
// two-column text, the metadata comments, and the errors (line number and what is wrong).
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "common/gps_time.hpp"
#include "processor/svp/cast.hpp"

namespace {

using namespace pitmap::proc::svp;

std::int64_t GpsAt(int y, int mo, int d, int h, int mi, int s) {
    pitmap::UtcCalendar c;
    c.year = y;
    c.month = mo;
    c.day = d;
    c.hour = h;
    c.minute = mi;
    c.second = s;
    return pitmap::GpsFromUnix(*pitmap::UnixFromUtcCalendar(c));
}

const char* kCaris =
    "[SVP_VERSION_2]\n"
    "pit.svp\n"
    "Section 2026-166 09:00:00 40:26:36.60 -007:46:50.16 morning cast\n"
    "0.0 1495.2\n"
    "2.5 1494.8\n"
    "\t6.0\t1470.1\n"
    "Section 2026-166 13:30 40:26:37.00 -007:46:51.00\n"
    "0.5 1497.0\n"
    "12.0 1452.0\n";

TEST(CastReader, CarisSectionsWithTimeAndPosition) {
    const auto r = ParseCastText(kCaris, "pit.svp");
    ASSERT_TRUE(r) << r.error().message;
    ASSERT_EQ(r->size(), 2u);
    const SoundSpeedCast& a = (*r)[0];
    EXPECT_EQ(a.utime_gps, GpsAt(2026, 6, 15, 9, 0, 0));  // day 166 of 2026 = 15 June
    EXPECT_NEAR(a.latitude_deg, 40 + 26 / 60.0 + 36.6 / 3600, 1e-12);
    EXPECT_NEAR(a.longitude_deg, -(7 + 46 / 60.0 + 50.16 / 3600), 1e-12);
    ASSERT_EQ(a.depth_m.size(), 3u);
    EXPECT_DOUBLE_EQ(a.depth_m[2], 6.0);
    EXPECT_DOUBLE_EQ(a.speed_mps[2], 1470.1);
    EXPECT_EQ((*r)[1].utime_gps, GpsAt(2026, 6, 15, 13, 30, 0));
    EXPECT_TRUE(ValidateCast(a).empty());
    // Written back, it reads the same.
    const auto again = ParseCastText(FormatCarisSvp(*r, "pit.svp"), "again.svp");
    ASSERT_TRUE(again) << again.error().message;
    ASSERT_EQ(again->size(), 2u);
    EXPECT_EQ((*again)[1].utime_gps, (*r)[1].utime_gps);
    EXPECT_NEAR((*again)[0].longitude_deg, a.longitude_deg, 1e-5);
    EXPECT_EQ((*again)[0].speed_mps, a.speed_mps);
}

TEST(CastReader, CsvWithHeaderAndMetadata) {
    const auto r = ParseCastText(
        "# time: 2026-06-15T09:10:00Z\n# position: 40.4435 -7.7806\n"
        "Depth (m),Speed (m/s),Temp\n0,1496.0,21.0\n3.5,1490.25,19\n10;1455\n",
        "cast.csv");
    ASSERT_TRUE(r) << r.error().message;
    ASSERT_EQ(r->size(), 1u);
    EXPECT_EQ((*r)[0].utime_gps, GpsAt(2026, 6, 15, 9, 10, 0));
    EXPECT_DOUBLE_EQ((*r)[0].latitude_deg, 40.4435);
    EXPECT_EQ((*r)[0].depth_m, (std::vector<double>{0, 3.5, 10}));
    EXPECT_EQ((*r)[0].speed_mps, (std::vector<double>{1496.0, 1490.25, 1455}));
}

TEST(CastReader, TwoColumnCastWithoutTime) {
    const auto r = ParseCastText("# a plain cast\n0.5 1495\n  4  1480.5\n\n20 1450\n", "cast.txt");
    ASSERT_TRUE(r) << r.error().message;
    EXPECT_FALSE((*r)[0].has_time());
    EXPECT_FALSE((*r)[0].has_position());
    EXPECT_EQ((*r)[0].depth_m.size(), 3u);
}

void ExpectError(const std::string& text, const std::string& where, const std::string& what) {
    const auto r = ParseCastText(text, "f.svp");
    ASSERT_FALSE(r) << text;
    EXPECT_NE(r.error().message.find(where), std::string::npos) << r.error().message;
    EXPECT_NE(r.error().message.find(what), std::string::npos) << r.error().message;
}

TEST(CastReader, ErrorsNameTheLineAndTheProblem) {
    ExpectError("0 1495\n5 1490\n5 1480\n", "f.svp:3:", "not below the previous depth");
    ExpectError("0 1495\n5 abc\n", "f.svp:2:", "sound speed 'abc' is not a number");
    ExpectError("0 1495\n5 2500\n", "f.svp:2:", "outside [1300, 1800]");
    ExpectError("0 1495 12\n", "f.svp:1:", "expected two columns");
    ExpectError("0 1495\n-5 1490\n", "f.svp:2:", "outside [-1, 12000] m");
    ExpectError("0 nan\n", "f.svp:1:", "not a number");
    ExpectError("# only comments\n", "f.svp", "no depth/speed data");
    ExpectError("0,1495\n1\n", "f.svp:2:", "expected 'depth,speed'");
    ExpectError("Speed,Depth\n1495,0\n", "f.svp:1:", "first column must be the depth");
    ExpectError("# time: yesterday\n0 1495\n", "f.svp:1:", "'# time:' needs UTC");
    ExpectError("[SVP_VERSION_2]\nx.svp\n0 1495\n", "f.svp:3:", "before the first 'Section'");
    ExpectError("[SVP_VERSION_2]\nx.svp\nSection 2026-400 10:00:00 0 0\n0 1495\n",
                "f.svp:3:",
                "not YYYY-DDD HH:MM:SS");
    ExpectError("[SVP_VERSION_2]\nx.svp\nSection 2025-366 10:00:00 0 0\n0 1495\n",
                "f.svp:3:",
                "day of year");
    ExpectError("[SVP_VERSION_2]\nx.svp\nSection 2026-100 10:00:00 95:00:00 0\n0 1495\n",
                "f.svp:3:",
                "latitude");
    ExpectError(
        "[SVP_VERSION_2]\nx.svp\nSection 2026-100 10:00:00 0 0\nSection 2026-100 "
        "11:00:00 0 0\n0 1495\n",
        "f.svp:3:",
        "section without data");
    ExpectError("[SVP_VERSION_9]\nx\n", "f.svp:1:", "unsupported CARIS version");
    ExpectError(std::string("0 1495\n\0", 8), "f.svp", "NUL");
}

}  // namespace
