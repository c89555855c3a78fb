// SPDX-License-Identifier: MIT
// GPS time: week/time-of-week, GPS <-> UTC with a leap-second table, Unix host time.
//
// Canonical representation: int64 microseconds since the GPS epoch (1980-01-06 00:00:00 on the
// GPS time scale, which has no leap seconds), named `utime_gps`. Host times are Unix
// microseconds (UTC, leap seconds not counted), named `utime` / `utime_host`.
// 0 means "unknown" in every message that carries a utime_gps.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

namespace pitmap {

inline constexpr std::int64_t kMicrosPerSecond = 1'000'000;
inline constexpr std::int64_t kSecondsPerWeek = 604'800;
inline constexpr std::int64_t kMicrosPerWeek = kSecondsPerWeek * kMicrosPerSecond;
// 1980-01-06T00:00:00Z in Unix seconds.
inline constexpr std::int64_t kGpsEpochUnixSeconds = 315'964'800;

struct GpsWeekTow {
    int week = 0;             // full GPS week number (not modulo 1024)
    std::int64_t tow_us = 0;  // microseconds of week, 0 .. kMicrosPerWeek-1
    double tow_s() const { return static_cast<double>(tow_us) * 1e-6; }
};

// Week + seconds of week (rounded to the microsecond) -> GPS microseconds. A time of week
// outside [0, 604800) is normalised into the neighbouring week.
std::int64_t GpsUtimeFromWeekTow(int week, double tow_s);
// Week + integer milliseconds of week (NovAtel binary headers) -> GPS microseconds.
std::int64_t GpsUtimeFromWeekMs(int week, std::int64_t ms_of_week);
// GPS microseconds (>= 0) -> week and time of week.
GpsWeekTow WeekTowFromGpsUtime(std::int64_t utime_gps);

// GPS - UTC in seconds at a UTC instant given as Unix microseconds (0 before 1981-07-01).
int LeapSecondsAtUnix(std::int64_t utime_unix);
// GPS - UTC in seconds at a GPS instant.
int LeapSecondsAtGps(std::int64_t utime_gps);
// Unix (UTC) microseconds -> GPS microseconds, using the table.
std::int64_t GpsFromUnix(std::int64_t utime_unix);
// GPS microseconds -> Unix (UTC) microseconds, using the table. During an inserted leap second
// (23:59:60 UTC) the result repeats the following second, as Unix time itself does.
std::int64_t UnixFromGps(std::int64_t utime_gps);
// Same conversions with a known GPS - UTC offset (e.g. from the receiver's TIME log), which
// wins over the table when the table is out of date.
inline std::int64_t GpsFromUnix(std::int64_t utime_unix, int leap_seconds) {
    return utime_unix - kGpsEpochUnixSeconds * kMicrosPerSecond + leap_seconds * kMicrosPerSecond;
}
inline std::int64_t UnixFromGps(std::int64_t utime_gps, int leap_seconds) {
    return utime_gps + kGpsEpochUnixSeconds * kMicrosPerSecond - leap_seconds * kMicrosPerSecond;
}
// The last date the built-in table is known to be complete for, "YYYY-MM-DD".
const char* LeapSecondTableValidUntil();

// Civil UTC date and time <-> Unix microseconds (proleptic Gregorian calendar).
struct UtcCalendar {
    int year = 1970;
    int month = 1;   // 1..12
    int day = 1;     // 1..31
    int hour = 0;    // 0..23
    int minute = 0;  // 0..59
    int second = 0;  // 0..60 (60 only during a leap second)
    int microsecond = 0;
};
// Returns nullopt for a field out of range (month 13, day 32, Feb 30, ...).
std::optional<std::int64_t> UnixFromUtcCalendar(const UtcCalendar& c);
UtcCalendar UtcCalendarFromUnix(std::int64_t utime_unix);
// ISO 8601 with microseconds and a Z, e.g. "2019-09-10T18:57:46.000000Z".
std::string FormatUnixIso8601(std::int64_t utime_unix);

}  // namespace pitmap
