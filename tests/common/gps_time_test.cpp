// SPDX-License-Identifier: MIT
#include "common/gps_time.hpp"

#include <gtest/gtest.h>

namespace pitmap {
namespace {

std::int64_t Unix(int y, int mo, int d, int h = 0, int mi = 0, int s = 0) {
    return *UnixFromUtcCalendar({y, mo, d, h, mi, s, 0});
}

TEST(GpsTime, EpochIsSixthOfJanuary1980) {
    EXPECT_EQ(Unix(1980, 1, 6) / kMicrosPerSecond, kGpsEpochUnixSeconds);
    EXPECT_EQ(GpsFromUnix(Unix(1980, 1, 6)), 0);
    EXPECT_EQ(UnixFromGps(0), Unix(1980, 1, 6));
}

TEST(GpsTime, WeekTowRoundTrip) {
    const std::int64_t t = GpsUtimeFromWeekTow(2070, 241084.0);
    const GpsWeekTow wt = WeekTowFromGpsUtime(t);
    EXPECT_EQ(wt.week, 2070);
    EXPECT_EQ(wt.tow_us, 241084LL * kMicrosPerSecond);
    EXPECT_EQ(GpsUtimeFromWeekMs(2070, 241084000), t);
    EXPECT_EQ(GpsUtimeFromWeekTow(2209, 490712.123456), GpsUtimeFromWeekMs(2209, 490712123) + 456);
}

TEST(GpsTime, WeekRolloverNormalises) {
    // The last microsecond of week 2069 and the first of 2070 are one microsecond apart.
    const std::int64_t end = GpsUtimeFromWeekTow(2069, 604799.999999);
    const std::int64_t start = GpsUtimeFromWeekTow(2070, 0.0);
    EXPECT_EQ(start - end, 1);
    const GpsWeekTow wt = WeekTowFromGpsUtime(end + 1);
    EXPECT_EQ(wt.week, 2070);
    EXPECT_EQ(wt.tow_us, 0);
    // A time of week past the end of the week lands in the next week.
    EXPECT_EQ(WeekTowFromGpsUtime(GpsUtimeFromWeekTow(2069, 604800.5)).week, 2070);
    // 1024-week rollover of the legacy 10-bit week is not applied: full weeks are kept.
    EXPECT_EQ(WeekTowFromGpsUtime(GpsUtimeFromWeekTow(1024, 0.0)).week, 1024);
}

TEST(GpsTime, LeapSecondTable) {
    EXPECT_EQ(LeapSecondsAtUnix(Unix(1980, 1, 6)), 0);
    EXPECT_EQ(LeapSecondsAtUnix(Unix(1981, 6, 30, 23, 59, 59)), 0);
    EXPECT_EQ(LeapSecondsAtUnix(Unix(1981, 7, 1)), 1);
    EXPECT_EQ(LeapSecondsAtUnix(Unix(2014, 11, 1)), 16);  // ProPak6 capture: TIME utc_offset -16
    EXPECT_EQ(LeapSecondsAtUnix(Unix(2016, 12, 31, 23, 59, 59)), 17);
    EXPECT_EQ(LeapSecondsAtUnix(Unix(2017, 1, 1)), 18);
    EXPECT_EQ(LeapSecondsAtUnix(Unix(2019, 9, 10)), 18);  // OEM7 capture: TIME utc_offset -18
}

TEST(GpsTime, ReferenceValueFromRealTimeLog) {
    // oem7 driver time.gps: header week 2070, 241084.000 s; body UTC 2019-09-10 18:57:46.000,
    // UTC offset -18 s (shared/specs/novatel_oem.md §4).
    const std::int64_t gps = GpsUtimeFromWeekTow(2070, 241084.0);
    EXPECT_EQ(UnixFromGps(gps), Unix(2019, 9, 10, 18, 57, 46));
    EXPECT_EQ(GpsFromUnix(Unix(2019, 9, 10, 18, 57, 46)), gps);
    EXPECT_EQ(UnixFromGps(gps, 18), Unix(2019, 9, 10, 18, 57, 46));
}

TEST(GpsTime, AcrossTheLeapSecondOf2016) {
    // 2017-01-01T00:00:00Z is GPS 18 s after 1980 + N; one second earlier in UTC it was 17.
    const std::int64_t after = GpsFromUnix(Unix(2017, 1, 1));
    const std::int64_t before = GpsFromUnix(Unix(2016, 12, 31, 23, 59, 59));
    // Two UTC seconds (23:59:59 and the inserted 23:59:60) elapsed in GPS time.
    EXPECT_EQ(after - before, 2 * kMicrosPerSecond);
    // Round trips away from the inserted second.
    EXPECT_EQ(UnixFromGps(after), Unix(2017, 1, 1));
    EXPECT_EQ(UnixFromGps(before), Unix(2016, 12, 31, 23, 59, 59));
    // The inserted second (GPS before + 1 s) maps onto the repeated Unix second.
    EXPECT_EQ(UnixFromGps(before + kMicrosPerSecond), Unix(2017, 1, 1));
    EXPECT_EQ(LeapSecondsAtGps(before + kMicrosPerSecond), 17);
    EXPECT_EQ(LeapSecondsAtGps(after), 18);
}

TEST(UtcCalendar, RejectsImpossibleDates) {
    EXPECT_FALSE(UnixFromUtcCalendar({2019, 2, 29, 0, 0, 0, 0}));
    EXPECT_TRUE(UnixFromUtcCalendar({2020, 2, 29, 0, 0, 0, 0}));
    EXPECT_FALSE(UnixFromUtcCalendar({1900, 2, 29, 0, 0, 0, 0}));
    EXPECT_TRUE(UnixFromUtcCalendar({2000, 2, 29, 0, 0, 0, 0}));
    EXPECT_FALSE(UnixFromUtcCalendar({2019, 13, 1, 0, 0, 0, 0}));
    EXPECT_FALSE(UnixFromUtcCalendar({2019, 4, 31, 0, 0, 0, 0}));
    EXPECT_FALSE(UnixFromUtcCalendar({2019, 4, 1, 24, 0, 0, 0}));
    EXPECT_FALSE(UnixFromUtcCalendar({2019, 4, 1, 0, 0, 0, 1000000}));
}

TEST(UtcCalendar, RoundTripAndFormat) {
    const std::int64_t t = *UnixFromUtcCalendar({2026, 11, 23, 3, 36, 15, 123456});
    const UtcCalendar c = UtcCalendarFromUnix(t);
    EXPECT_EQ(c.year, 2026);
    EXPECT_EQ(c.month, 11);
    EXPECT_EQ(c.day, 23);
    EXPECT_EQ(c.hour, 3);
    EXPECT_EQ(c.minute, 36);
    EXPECT_EQ(c.second, 15);
    EXPECT_EQ(c.microsecond, 123456);
    EXPECT_EQ(FormatUnixIso8601(t), "2026-11-23T03:36:15.123456Z");
    EXPECT_EQ(FormatUnixIso8601(-1), "1969-12-31T23:59:59.999999Z");
}

}  // namespace
}  // namespace pitmap
