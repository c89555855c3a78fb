// SPDX-License-Identifier: MIT
#include "processor/io/lcm_messages.hpp"

#include <pitmap/ins_pva_t.hpp>
#include <pitmap/ins_stddev_t.hpp>
#include <pitmap/multibeam_ping_t.hpp>

#include "processor/io/ingest_collect.hpp"

namespace pitmap::proc::io {

survey::NavStdDev NavStdDevOf(const pitmap::ins_pva_t& m) {
    return detail::StdDevOf(m.utime_gps, m);
}
survey::NavStdDev NavStdDevOf(const pitmap::ins_stddev_t& m) {
    return detail::StdDevOf(m.utime_gps, m);
}

survey::NavSample NavSampleOf(const pitmap::ins_pva_t& m) {
    return detail::FromPva(m.utime_gps,
                           m.latitude_deg,
                           m.longitude_deg,
                           m.height_ellipsoid_m,
                           m.velocity_north_mps,
                           m.velocity_east_mps,
                           m.velocity_up_mps,
                           m.roll_deg,
                           m.pitch_deg,
                           m.azimuth_deg,
                           m.ins_status,
                           m.position_type);
}

survey::PingHeader PingHeaderOf(const pitmap::multibeam_ping_t& m) {
    survey::PingHeader h;
    h.utime_gps = m.utime_gps;
    h.ping_number = m.ping_number;
    h.sound_speed_mps = m.sound_speed_mps;
    h.sound_speed_valid = m.sound_speed_valid != 0;
    h.range_resolution_m = m.range_resolution_m;
    h.start_angle_deg = m.start_angle_deg;
    h.angle_increment_deg = m.angle_increment_deg;
    h.profile_tilt_deg = m.profile_tilt_deg;
    // The topside's NMEA fix the header carried (the daemon decoded it): the INS's slow error
    // is checked against it (calib::EstimateInsSlowError, docs/decisions/027).
    h.aid_latitude_deg = m.header_latitude_deg;
    h.aid_longitude_deg = m.header_longitude_deg;
    return h;
}

}  // namespace pitmap::proc::io
