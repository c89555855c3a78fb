// SPDX-License-Identifier: MIT
// Sound-velocity casts in the files probes and their programs write. Pure: the caller reads
// the file; ParseCastText (cast.hpp) calls these when it recognises one of them by content.
//
// What each format carries (time always UTC in the cast; a position of 0 0 means unknown):
//  - AML Base.X2 .csv (kAml): `[cast header]`, `[Instrument]` with Date= Time= Latitude=
//    Longitude=, `[Data.X]` with the Latitude= Longitude= of its GPS (wins over [Instrument]'s),
//    `[data]` then rows `YYYY-MM-DD,HH:MM:SS.ss,SV,P,T` (sound speed m/s, pressure dbar,
//    temperature degC: the slots' order, no column header). Time: Date/Time of the header
//    (the instrument clock, assumed UTC), else the first row's.
//  - SonTek CastAway .csv (kCastAway): `% Key,value` header with `Cast time (UTC)` and
//    `Start latitude`/`Start longitude`, then a column header. Columns found by name:
//    `Depth (Meter)` (else `Pressure (Decibar)` to depth), `Sound velocity` (else computed from
//    `Temperature`, `Salinity` or `Conductivity (MicroSiemens...)`, and pressure).
//  - HYPACK .vel (kHypackVel): `FTP NEW n LAT LON HH:MM MM/DD/YYYY` (decimal degrees; time
//    assumed UTC), then `depth speed` rows.
//  - Kongsberg SIS .asvp (kKongsbergAsvp): `( SoundVelocity 1.0 0 YYYYMMDDHHMM LAT LON ... N )`
//    (UTC; the last field before `)` is the number of points, checked), then `depth speed`.
//  - Simrad sentences $xxS10 (kSimradS10, Simrad .ssp) and $xxS12 (kSimradS12, MVP .s12):
//    `$xxS1n,counter,N,hhmmss,dd,mm,yyyy,` then N points of comma-separated values (depth,
//    speed, then temperature, salinity, ...: S10 5 values a point, S12 as many as the count
//    gives), S12 then `ddmm.mm,N|S,dddmm.mm,E|W,...,source*hh`; the sentence may be broken
//    over lines and ends with a `\` line. UTC. The checksum is not checked (the MVP's own
//    file does not match its checksum in any line layout). N is checked (truncation).
//  - Sea-Bird .cnv (kSeaBirdCnv): `*` and `#` header lines up to `*END*`: `# nquan`,
//    `# name i = short: long`, `# bad_flag`, time from `* NMEA UTC (Time) =`, else the
//    instrument's `* cast ... dd Mon yyyy hh:mm:ss` line (its clock, assumed UTC), else
//    `# start_time` unless it is the upload time; position from `* NMEA Latitude/Longitude =`
//    (`dd mm.mm N`). Columns by short name: depth `depS`/`depF` (m), else pressure `pr*` (dbar)
//    to depth; speed `sv*`, else computed from temperature `t090`/`t190`/`tv290` (ITS-90) or
//    `t068` (IPTS-68), salinity `sal*` or conductivity `c0`/`c1` (S/m, mS/cm or uS/cm) and
//    pressure. A row whose `flag` column is not 0, or with the bad flag, is dropped.
//  - Valeport MIDAS .000 (kValeportMidas): `Key :<TAB>value` header (`Time Stamp`), then the
//    tab-separated column header `Date / Time<TAB>SOUND VELOCITY;M/SEC<TAB>PRESSURE;DBAR...` and
//    rows `DD/MM/YYYY HH:MM:SS<TAB>...` (day first, Valeport's default, unless the first
//    number is > 12; the probe clock, assumed UTC). Speed: the measured `SOUND VELOCITY`,
//    else computed from `TEMPERATURE`, `Calc. SALINITY` or `CONDUCTIVITY` and pressure. No
//    position.
// Without a position, depth from pressure uses latitude 45 deg (gravity differs by < 0.3 %).
//
// Computed speed: UNESCO 1983 Chen & Millero from temperature, practical salinity and pressure
// (salinity from conductivity by PSS-78 with Hill's fresh-water extension); depth from
// pressure: UNESCO 1983 (seawater.hpp, which says why).
//
// The down-cast rule (DownCast), for every probe format (a no-op on an edited profile):
//  1. A row whose speed is outside [kMinSpeedMps, kMaxSpeedMps], whose depth is outside
//     [-1, 12000] m, or that a format flags bad, is dropped and counted (a probe in air).
//  2. The up cast: the samples after the first deepest one are dropped.
//  3. The surface soak: the descent starts at the last sample, in the upper half of the cast,
//     ending kSoakSamples + 1 samples that span less than kSoakSpan_m in depth (the probe held
//     still); the samples before it are dropped. No such sample: the descent is the whole.
//  4. Thinning: a sample of the descent is kept only if it is deeper than every one kept
//     before it (strictly increasing depth; the first sample at each depth wins).
//
// How it fails: a line that does not parse (a number, a field count, a header) is an error
// "NAME:LINE: what"; a file that ends before its declared points, or before its data, is an
// error naming the file; a cast with no valid sample left is an error. Values that parse but
// are implausible are data: dropped and counted in ProbeCastStats.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

#include "common/result.hpp"
#include "processor/svp/cast.hpp"

namespace pitmap::proc::svp {

inline constexpr int kSoakSamples = 8;      // a soak is this many steps ...
inline constexpr double kSoakSpan_m = 0.1;  // ... spanning less than this depth

struct ProbeCastStats {
    CastFormat format = CastFormat::kAuto;
    std::size_t rows = 0;              // data rows read
    std::size_t invalid = 0;           // dropped by rule 1
    std::size_t up_cast = 0;           // dropped by rule 2
    std::size_t soak = 0;              // dropped by rule 3
    std::size_t thinned = 0;           // dropped by rule 4
    bool speed_computed = false;       // no speed column: Chen & Millero
    bool depth_from_pressure = false;  // no depth column: UNESCO 1983
};

// The probe format of a text by its first lines, or kAuto when it is none of them.
CastFormat SniffProbeFormat(std::string_view text);

// Parses a probe file of `format` (one of the probe formats above) into one cast after the
// down-cast rule; `stats` (optional) receives the counts.
Expected<SoundSpeedCast> ParseProbeCast(std::string_view text,
                                        const std::string& name,
                                        CastFormat format,
                                        ProbeCastStats* stats = nullptr);

// Rules 2-4 on a series of depths (rule 1 applied by the caller): the indices kept, in order.
std::vector<std::size_t> DownCast(const std::vector<double>& depth_m, ProbeCastStats* stats);

}  // namespace pitmap::proc::svp
