// SPDX-License-Identifier: MIT
// The survey model in one binary file, P/survey.pitmap: what `pitmap georef` makes and every
// later stage command loads and saves (survey.hpp says what it holds).
//
// Layout (native byte order for the framing and the arrays of numbers; the ping and navigation
// records field by field in the little-endian layout of survey_records.hpp; read only by a
// build that knows the format version, on the same byte order):
//   u8[8] magic "PMSURVEY", u32 format version (kSurveyFormatVersion), u32 byte order (1 little,
//   2 big), u32 number of sections; then each section as
//   char[16] tag (NUL padded), u64 payload bytes, u32 CRC-32 of the payload, the payload.
// Sections (each once; "state" and "ingest" are required):
//   state                 JSON text: vehicle file, nominal and current mount, world origin,
//                         sonar clock, refraction record, calibration state
//   ingest                i32 leap seconds, u32 ping clock, then nav samples, nav stddevs, ping
//                         headers (records of survey_records.hpp) and u32 range counts, each
//                         as u64 count, u64 element (record) size, bytes
//   intensity             (format 2; only when the pings carry intensities) u16 per-beam 83P
//                         intensities beside the range counts (one per count, 0 = none), as
//                         u64 count, u64 element size, bytes
//   beam_angle            (format 3; only when the pings carry their own beam angles) f32
//                         per-beam angles in degrees beside the range counts (one per count,
//                         NaN = the header's), as u64 count, u64 element size, bytes
//   cleaning              (format 4; only once the cleaning ran) the soundings it rejected:
//                         u64 number of soundings (= range counts), then the rejected ones'
//                         u32 indices (ascending) and u8 statuses (survey/sounding_status.hpp),
//                         each as u64 count, u64 element size, bytes
//   traj.ins, traj.calibrated, traj.slam
//                         u64 count, u64 element size, then per ping: f64 x, y, z, qw, qx, qy,
//                         qz (T_world_vehicle), u32 valid, u32 zero
//   traj.slam.sigma       (format 6; only when SLAM computed its posterior) u64 count, u64
//                         element size, then per ping f64 roll, pitch, yaw (rad), east, north,
//                         up (m): the SLAM trajectory's 1-sigma, NaN where unknown
// The reader checks every length and count against the bytes left before allocating (memory
// stays bounded by the file size), every section's CRC, and the consistency of what it read
// (beam offsets inside the range counts and in ping order without overlap, one pose per
// ping, finite poses); anything else is an
// error naming the file and what is wrong.
#pragma once

#include <cstdint>
#include <string>

#include "common/result.hpp"
#include "processor/survey/survey.hpp"

namespace pitmap::proc::survey {

// 2: the optional intensity section. 3: the optional beam_angle section (a format 2 reader
// would call it an unknown section). 4: the optional cleaning section. 5: the ping records field
// by field (survey_records.hpp), no longer PingHeader's memory layout. Formats 1 to 5 are still
// read (without the sections they lack; their ping records in the old layout); any other format
// is an error that says to run `pitmap georef` again. 6: the optional traj.slam.sigma section
// (format 5 files are read without it).
inline constexpr std::uint32_t kSurveyFormatVersion = 6;
inline constexpr const char* kSurveyFileName = "survey.pitmap";

// Writes to PATH.partial and renames it over PATH, so that a full disk or a crash leaves the
// previous file whole.
Status SaveSurvey(const std::string& path, const SurveyModel& m);

enum class LoadParts {
    kAll,    // everything
    kState,  // the state section only: no ingest, no trajectories (mesh, report)
};
Expected<SurveyModel> LoadSurvey(const std::string& path, LoadParts parts = LoadParts::kAll);

}  // namespace pitmap::proc::survey
