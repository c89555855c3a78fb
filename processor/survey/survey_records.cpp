// SPDX-License-Identifier: MIT
#include "processor/survey/survey_records.hpp"

namespace pitmap::proc::survey::records {

void WritePing(ByteWriter& w, const survey::PingHeader& p) {
    w.I64Le(p.utime_gps);
    w.I64Le(p.ping_number);
    w.F64Le(p.sound_speed_mps);
    w.U8(p.sound_speed_valid ? 1 : 0);
    w.F64Le(p.range_resolution_m);
    w.F64Le(p.start_angle_deg);
    w.F64Le(p.angle_increment_deg);
    w.F64Le(p.profile_tilt_deg);
    w.U32Le(p.beam_offset);
    w.U16Le(p.num_beams);
    w.U8(p.aid_attitude_at_ping ? 1 : 0);
    w.F64Le(p.aid_latitude_deg);
    w.F64Le(p.aid_longitude_deg);
    w.F64Le(p.aid_roll_deg);
    w.F64Le(p.aid_pitch_deg);
    w.F64Le(p.aid_heading_deg);
}

namespace {

// The ping fields in their order, with the padding formats 1-4 held after sound_speed_valid and
// after aid_attitude_at_ping (none in format 5).
survey::PingHeader ReadPingFields(ByteReader& r,
                                  std::size_t pad_after_valid,
                                  std::size_t pad_after_flag) {
    survey::PingHeader p;
    p.utime_gps = r.I64Le();
    p.ping_number = r.I64Le();
    p.sound_speed_mps = r.F64Le();
    p.sound_speed_valid = r.U8() != 0;
    r.Skip(pad_after_valid);
    p.range_resolution_m = r.F64Le();
    p.start_angle_deg = r.F64Le();
    p.angle_increment_deg = r.F64Le();
    p.profile_tilt_deg = r.F64Le();
    p.beam_offset = r.U32Le();
    p.num_beams = r.U16Le();
    p.aid_attitude_at_ping = r.U8() != 0;
    r.Skip(pad_after_flag);
    p.aid_latitude_deg = r.F64Le();
    p.aid_longitude_deg = r.F64Le();
    p.aid_roll_deg = r.F64Le();
    p.aid_pitch_deg = r.F64Le();
    p.aid_heading_deg = r.F64Le();
    return p;
}

}  // namespace

survey::PingHeader ReadPing(ByteReader& r) {
    return ReadPingFields(r, 0, 0);
}

survey::PingHeader ReadLegacyPing(ByteReader& r) {
    // Offsets as formats 1-4 held them: 7 bytes of padding after sound_speed_valid (24) and
    // one after aid_attitude_at_ping (70).
    return ReadPingFields(r, 7, 1);
}

void WriteNav(ByteWriter& w, const survey::NavSample& s) {
    w.I64Le(s.utime_gps);
    w.F64Le(s.position.latitude_deg);
    w.F64Le(s.position.longitude_deg);
    w.F64Le(s.position.height_m);
    w.F64Le(s.roll_rad);
    w.F64Le(s.pitch_rad);
    w.F64Le(s.yaw_rad);
    for (int i = 0; i < 3; ++i) w.F64Le(s.velocity_enu_mps[i]);
    w.I32Le(s.ins_status);
    w.I32Le(s.position_type);
}

survey::NavSample ReadNav(ByteReader& r) {
    survey::NavSample s;
    s.utime_gps = r.I64Le();
    s.position.latitude_deg = r.F64Le();
    s.position.longitude_deg = r.F64Le();
    s.position.height_m = r.F64Le();
    s.roll_rad = r.F64Le();
    s.pitch_rad = r.F64Le();
    s.yaw_rad = r.F64Le();
    for (int i = 0; i < 3; ++i) s.velocity_enu_mps[i] = r.F64Le();
    s.ins_status = r.I32Le();
    s.position_type = r.I32Le();
    return s;
}

void WriteStdDev(ByteWriter& w, const survey::NavStdDev& s) {
    w.I64Le(s.utime_gps);
    for (const float v : {s.north_m, s.east_m, s.up_m, s.roll_deg, s.pitch_deg, s.yaw_deg})
        w.F32Le(v);
}

survey::NavStdDev ReadStdDev(ByteReader& r) {
    survey::NavStdDev s;
    s.utime_gps = r.I64Le();
    for (float* v : {&s.north_m, &s.east_m, &s.up_m, &s.roll_deg, &s.pitch_deg, &s.yaw_deg})
        *v = r.F32Le();
    return s;
}

}  // namespace pitmap::proc::survey::records
