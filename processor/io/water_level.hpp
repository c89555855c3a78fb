// SPDX-License-Identifier: MIT
// Water-level time series (the vertical datum's `water_level_source: file`): CSV text, one
// observation a line,
//   time,level
// time: UTC as ISO 8601 "YYYY-MM-DDTHH:MM:SS[.fff]Z" (or a space for T); level: the water
// surface above the datum in metres. Separators ',' ';' or tabs; blank lines and lines
// starting with '#' are skipped; one header line whose first field starts with a letter
// other than a digit (e.g. "time,level_m") is allowed before the first observation; further
// columns are ignored. Times must increase strictly. At most kMaxWaterLevels lines.
// Failure model: every problem is an error naming the file and the line; nothing is skipped
// silently.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "common/result.hpp"

namespace pitmap::proc::io {

struct WaterLevelSample {
    std::int64_t utime_gps = 0;  // GPS microseconds
    double level_m = 0;          // water surface above the datum, m
};

inline constexpr std::size_t kMaxWaterLevels = 10'000'000;
inline constexpr std::uintmax_t kMaxWaterLevelFileBytes = 256u << 20;

Expected<std::vector<WaterLevelSample>> ParseWaterLevelText(std::string_view text,
                                                            const std::string& name);
// Reads and parses a file (at most kMaxWaterLevelFileBytes).
Expected<std::vector<WaterLevelSample>> ReadWaterLevelFile(const std::string& path);

}  // namespace pitmap::proc::io
