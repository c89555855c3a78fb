// SPDX-License-Identifier: MIT
// The survey file's fixed-size records (survey_file.hpp), written field by field in a stated
// little-endian layout through common's ByteWriter, so that the bytes do not depend on how a
// struct lies in memory: reordering or adding a field of PingHeader changes nothing on disk
// until these functions and the format version change with it.
//
//   ping (format 5, 104 bytes): i64 utime_gps, i64 ping_number, f64 sound_speed_mps,
//     u8 sound_speed_valid, f64 range_resolution_m, f64 start_angle_deg,
//     f64 angle_increment_deg, f64 profile_tilt_deg, u32 beam_offset, u16 num_beams,
//     u8 aid_attitude_at_ping, f64 aid_latitude_deg, aid_longitude_deg, aid_roll_deg,
//     aid_pitch_deg, aid_heading_deg
//   ping (formats 1-4, 112 bytes): the same fields as the x86-64 and arm64 compilers laid out
//     PingHeader then (padding after sound_speed_valid and aid_attitude_at_ping); read only
//   nav sample (88 bytes): i64 utime_gps, f64 latitude_deg, longitude_deg, height_m, roll_rad,
//     pitch_rad, yaw_rad, velocity east, north, up (m/s), i32 ins_status, i32 position_type
//   nav standard deviation (32 bytes): i64 utime_gps, f32 north_m, east_m, up_m, roll_deg,
//     pitch_deg, yaw_deg
// A bool is written as 0 or 1 and read as "not 0". The nav records are laid out as formats 1-4
// wrote them on little-endian machines, so every format reads them the same way.
#pragma once

#include <cstddef>

#include "common/byte_io.hpp"
#include "processor/survey/series.hpp"

namespace pitmap::proc::survey::records {

inline constexpr std::size_t kPingBytes = 104;
inline constexpr std::size_t kLegacyPingBytes = 112;
inline constexpr std::size_t kNavBytes = 88;
inline constexpr std::size_t kStdDevBytes = 32;

void WritePing(ByteWriter& w, const survey::PingHeader& p);
// Reads kPingBytes (format 5 and later).
survey::PingHeader ReadPing(ByteReader& r);
// Reads kLegacyPingBytes (formats 1-4).
survey::PingHeader ReadLegacyPing(ByteReader& r);

void WriteNav(ByteWriter& w, const survey::NavSample& s);
survey::NavSample ReadNav(ByteReader& r);

void WriteStdDev(ByteWriter& w, const survey::NavStdDev& s);
survey::NavStdDev ReadStdDev(ByteReader& r);

}  // namespace pitmap::proc::survey::records
