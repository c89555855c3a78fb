// SPDX-License-Identifier: MIT
// Sound-velocity casts and their text formats. Pure: the caller reads the file.
//
// Formats (ParseCastText, `format` kAuto picks one from the text; the probes' own formats are
// described in processor/svp/probe_casts.hpp):
//  - CARIS .svp (HIPS and SIPS "SVP Files"): line 1 `[SVP_VERSION_2]` (or _1), line 2 the file
//    name, then one or more sections, each a heading
//      Section YYYY-DDD HH:MM[:SS] LAT LON [comment]
//    (year, day of year, UTC time; LAT/LON as DD:MM:SS.ss with a sign or decimal degrees)
//    followed by `depth speed` lines (metres, m/s; whitespace separated).
//  - CSV: `depth,speed[,more columns ignored]` per line (',' or ';'), an optional header line
//    naming the columns (its first column must start with "depth").
//  - Two-column text: `depth speed` per line, whitespace separated.
// In CSV and two-column files, '#' starts a comment; two comment keys give the cast's time and
// place: `# time: 2026-06-15T09:00:00Z` (UTC) and `# position: LAT LON` (decimal degrees).
// A cast without a time is valid from the start of the survey.
//
// Text whose first line is none of these (nor a probe format) is an error "NAME: not a
// sound-velocity cast format pitmap reads (known: ...)".
//
// Checks (each a clear error "NAME:LINE: what"): numbers parse and are finite, depth in
// [-1, 12000] m strictly increasing within a cast, speed in [1300, 1800] m/s, at least one
// point per cast, at most kMaxCastPoints points and kMaxCasts casts per file.
#pragma once

#include <cstdint>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include "common/result.hpp"

namespace pitmap::proc::svp {

inline constexpr std::size_t kMaxCastPoints = 100000;
inline constexpr std::size_t kMaxCasts = 10000;
inline constexpr double kMinSpeedMps = 1300.0;
inline constexpr double kMaxSpeedMps = 1800.0;

struct SoundSpeedCast {
    std::string name;            // file name, plus the section for multi-cast files
    std::int64_t utime_gps = 0;  // cast time (GPS us); 0 = unknown (valid from the start)
    double latitude_deg = std::numeric_limits<double>::quiet_NaN();  // NaN = unknown
    double longitude_deg = std::numeric_limits<double>::quiet_NaN();
    std::vector<double> depth_m;    // below the water surface, strictly increasing
    std::vector<double> speed_mps;  // sound speed at each depth
    bool has_time() const { return utime_gps != 0; }
    bool has_position() const { return latitude_deg == latitude_deg; }
};

// Text formats pitmap writes or takes from other software (above), then the probes' own files
// (processor/svp/probe_casts.hpp: what each carries, the down-cast rule, the equations).
enum class CastFormat {
    kAuto = 0,
    kCaris,
    kCsv,
    kTwoColumn,
    kAml,            // AML Oceanographic Base.X2 .csv ([cast header] ... [data])
    kCastAway,       // SonTek CastAway CTD .csv ('%' header)
    kHypackVel,      // HYPACK .vel (FTP NEW header)
    kKongsbergAsvp,  // Kongsberg SIS .asvp (( SoundVelocity ... ) header)
    kSimradS12,      // $xxS12 sentence (MVP .s12)
    kSeaBirdCnv,     // Sea-Bird SBE Data Processing .cnv
    kSimradS10,      // $xxS10 sentence (Simrad .ssp)
    kValeportMidas,  // Valeport MIDAS SVX2 / CTD .000 (tab-separated, 'Date / Time' columns)
};
const char* ToString(CastFormat f);
// Every format ParseCastText recognises by content, for messages ("caris, csv, ...").
std::string KnownCastFormats();

// Parses one file's text (`name` names it in messages and in the casts).
Expected<std::vector<SoundSpeedCast>> ParseCastText(std::string_view text,
                                                    const std::string& name,
                                                    CastFormat format = CastFormat::kAuto);

// Every problem of a cast built in code (the parser's checks, without line numbers).
std::vector<std::string> ValidateCast(const SoundSpeedCast& cast);

// CARIS .svp text of casts (every cast needs a time; position 0 0 when unknown).
std::string FormatCarisSvp(const std::vector<SoundSpeedCast>& casts, const std::string& file_name);

}  // namespace pitmap::proc::svp
