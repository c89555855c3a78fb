// SPDX-License-Identifier: MIT
#include "common/gps_time.hpp"

#include <array>
#include <cmath>
#include <cstdio>

namespace pitmap {
namespace {

// Days since 1970-01-01 of a proleptic Gregorian date (H. Hinnant's days_from_civil).
constexpr std::int64_t DaysFromCivil(std::int64_t y, unsigned m, unsigned d) {
    y -= m <= 2 ? 1 : 0;
    const std::int64_t era = (y >= 0 ? y : y - 399) / 400;
    const auto yoe = static_cast<unsigned>(y - era * 400);
    const unsigned doy = (153 * (m + (m > 2 ? static_cast<unsigned>(-3) : 9)) + 2) / 5 + d - 1;
    const unsigned doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    return era * 146097 + static_cast<std::int64_t>(doe) - 719468;
}

struct LeapEntry {
    std::int64_t unix_s;  // UTC instant from which the offset applies
    int gps_minus_utc_s;
};

// GPS - UTC from IERS Bulletin C. Each entry is the first UTC second after an inserted leap second.
constexpr std::array<LeapEntry, 18> kLeapTable = {{
    {DaysFromCivil(1981, 7, 1) * 86400, 1},
    {DaysFromCivil(1982, 7, 1) * 86400, 2},
    {DaysFromCivil(1983, 7, 1) * 86400, 3},
    {DaysFromCivil(1985, 7, 1) * 86400, 4},
    {DaysFromCivil(1988, 1, 1) * 86400, 5},
    {DaysFromCivil(1990, 1, 1) * 86400, 6},
    {DaysFromCivil(1991, 1, 1) * 86400, 7},
    {DaysFromCivil(1992, 7, 1) * 86400, 8},
    {DaysFromCivil(1993, 7, 1) * 86400, 9},
    {DaysFromCivil(1994, 7, 1) * 86400, 10},
    {DaysFromCivil(1996, 1, 1) * 86400, 11},
    {DaysFromCivil(1997, 7, 1) * 86400, 12},
    {DaysFromCivil(1999, 1, 1) * 86400, 13},
    {DaysFromCivil(2006, 1, 1) * 86400, 14},
    {DaysFromCivil(2009, 1, 1) * 86400, 15},
    {DaysFromCivil(2012, 7, 1) * 86400, 16},
    {DaysFromCivil(2015, 7, 1) * 86400, 17},
    {DaysFromCivil(2017, 1, 1) * 86400, 18},
}};

std::int64_t FloorDiv(std::int64_t a, std::int64_t b) {
    std::int64_t q = a / b;
    if ((a % b != 0) && ((a < 0) != (b < 0))) --q;
    return q;
}

}  // namespace

std::int64_t GpsUtimeFromWeekTow(int week, double tow_s) {
    return static_cast<std::int64_t>(week) * kMicrosPerWeek + std::llround(tow_s * 1e6);
}

std::int64_t GpsUtimeFromWeekMs(int week, std::int64_t ms_of_week) {
    return static_cast<std::int64_t>(week) * kMicrosPerWeek + ms_of_week * 1000;
}

GpsWeekTow WeekTowFromGpsUtime(std::int64_t utime_gps) {
    const std::int64_t week = FloorDiv(utime_gps, kMicrosPerWeek);
    return {static_cast<int>(week), utime_gps - week * kMicrosPerWeek};
}

int LeapSecondsAtUnix(std::int64_t utime_unix) {
    const std::int64_t s = FloorDiv(utime_unix, kMicrosPerSecond);
    int leap = 0;
    for (const LeapEntry& e : kLeapTable) {
        if (s >= e.unix_s) leap = e.gps_minus_utc_s;
    }
    return leap;
}

int LeapSecondsAtGps(std::int64_t utime_gps) {
    // Entry i takes effect at GPS second (unix_s - epoch + offset_i); the inserted second
    // itself (GPS time of 23:59:60) still belongs to the previous offset.
    const std::int64_t s = FloorDiv(utime_gps, kMicrosPerSecond);
    int leap = 0;
    for (const LeapEntry& e : kLeapTable) {
        if (s >= e.unix_s - kGpsEpochUnixSeconds + e.gps_minus_utc_s) leap = e.gps_minus_utc_s;
    }
    return leap;
}

std::int64_t GpsFromUnix(std::int64_t utime_unix) {
    return GpsFromUnix(utime_unix, LeapSecondsAtUnix(utime_unix));
}

std::int64_t UnixFromGps(std::int64_t utime_gps) {
    return UnixFromGps(utime_gps, LeapSecondsAtGps(utime_gps));
}

const char* LeapSecondTableValidUntil() {
    // IERS Bulletin C 70 (July 2025): no leap second at the end of December 2025.
    return "2026-06-30";
}

std::optional<std::int64_t> UnixFromUtcCalendar(const UtcCalendar& c) {
    static constexpr std::array<int, 12> kDays = {31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31};
    if (c.month < 1 || c.month > 12 || c.day < 1 || c.hour < 0 || c.hour > 23 || c.minute < 0 ||
        c.minute > 59 || c.second < 0 || c.second > 60 || c.microsecond < 0 ||
        c.microsecond >= 1'000'000) {
        return std::nullopt;
    }
    const bool leap_year = (c.year % 4 == 0 && c.year % 100 != 0) || c.year % 400 == 0;
    const int month_days =
        kDays[static_cast<std::size_t>(c.month - 1)] + (c.month == 2 && leap_year ? 1 : 0);
    if (c.day > month_days) return std::nullopt;
    const std::int64_t days =
        DaysFromCivil(c.year, static_cast<unsigned>(c.month), static_cast<unsigned>(c.day));
    const std::int64_t seconds = days * 86400 + c.hour * 3600 + c.minute * 60 + c.second;
    return seconds * kMicrosPerSecond + c.microsecond;
}

UtcCalendar UtcCalendarFromUnix(std::int64_t utime_unix) {
    const std::int64_t s = FloorDiv(utime_unix, kMicrosPerSecond);
    const std::int64_t days = FloorDiv(s, 86400);
    const std::int64_t sod = s - days * 86400;
    // civil_from_days (H. Hinnant).
    const std::int64_t z = days + 719468;
    const std::int64_t era = (z >= 0 ? z : z - 146096) / 146097;
    const auto doe = static_cast<unsigned>(z - era * 146097);
    const unsigned yoe = (doe - doe / 1460 + doe / 36524 - doe / 146096) / 365;
    const unsigned doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    const unsigned mp = (5 * doy + 2) / 153;
    const unsigned d = doy - (153 * mp + 2) / 5 + 1;
    const unsigned m = mp < 10 ? mp + 3 : mp - 9;
    UtcCalendar c;
    c.year = static_cast<int>(static_cast<std::int64_t>(yoe) + era * 400 + (m <= 2 ? 1 : 0));
    c.month = static_cast<int>(m);
    c.day = static_cast<int>(d);
    c.hour = static_cast<int>(sod / 3600);
    c.minute = static_cast<int>((sod % 3600) / 60);
    c.second = static_cast<int>(sod % 60);
    c.microsecond = static_cast<int>(utime_unix - s * kMicrosPerSecond);
    return c;
}

std::string FormatUnixIso8601(std::int64_t utime_unix) {
    const UtcCalendar c = UtcCalendarFromUnix(utime_unix);
    char buf[40];
    std::snprintf(buf,
                  sizeof buf,
                  "%04d-%02d-%02dT%02d:%02d:%02d.%06dZ",
                  c.year,
                  c.month,
                  c.day,
                  c.hour,
                  c.minute,
                  c.second,
                  c.microsecond);
    return buf;
}

}  // namespace pitmap
