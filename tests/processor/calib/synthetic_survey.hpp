// SPDX-License-Identifier: MIT
// A small synthetic survey for the clock and latency tests: a figure-of-eight track (it crosses
// itself, so passes overlap at different headings) over a rolling seabed, an INS at 50 Hz with
// wave roll and pitch, a multibeam at 10 Hz whose clock is `clock_error_s` off: a ping sent at
// GPS time t is stamped t + clock_error_s, so the correction to find is -clock_error_s.
#pragma once

#include <cmath>
#include <cstdint>

#include "common/frames.hpp"
#include "common/geodesy.hpp"
#include "processor/georef/georef.hpp"

namespace pitmap::proc::calib::testing {

inline double Seabed(double x, double y) {
    return -12.0 + 1.5 * std::sin(x / 6.0) + 1.0 * std::cos(y / 5.0) + 0.02 * x;
}

struct SyntheticSurvey {
    survey::NavSeries nav;
    survey::PingSeries pings;
    Geodetic origin{40.4435, -7.7806, 412.0};
    std::int64_t t0_utime = 1'400'000'000'000'000;  // GPS microseconds
};

struct SurveyOptions {
    double duration_s = 200;
    int num_beams = 121;  // over +-60 deg
    double clock_error_s = 0;
    double clock_rate_ppm = 0;  // ... and it runs this fast: + clock_rate_ppm * 1e-6 * t
    double roll_amplitude_deg = 2.0;
    double pitch_amplitude_deg = 1.0;
    bool header_position = false;  // 1 Hz NMEA fixes, stale by up to a ping + 0.15 s
    bool header_attitude = false;  // roll, pitch (head's own sensor) and heading at the ping
    survey::SonarMount truth;      // the mount the ranges are made with
};

// Vehicle state at time t (seconds since the start).
struct VehicleState {
    Eigen::Vector3d enu;
    double roll, pitch, yaw;  // rad
};
inline VehicleState StateAt(double t, const SurveyOptions& o) {
    const double w = 0.04;
    VehicleState s;
    s.enu = Eigen::Vector3d(20.0 * std::sin(w * t), 15.0 * std::sin(2 * w * t), 0.0);
    const double ve = 20.0 * w * std::cos(w * t), vn = 30.0 * w * std::cos(2 * w * t);
    s.yaw = std::atan2(ve, vn);
    s.roll = frames::DegToRad(o.roll_amplitude_deg) * std::sin(2 * M_PI * t / 3.5);
    s.pitch = frames::DegToRad(o.pitch_amplitude_deg) * std::sin(2 * M_PI * t / 5.3 + 0.7);
    return s;
}

inline SyntheticSurvey MakeSurvey(const SurveyOptions& o) {
    SyntheticSurvey sv;
    const LocalTangentFrame world(sv.origin);
    for (int i = 0; i <= static_cast<int>(o.duration_s * 50); ++i) {
        const double t = i / 50.0;
        const VehicleState v = StateAt(t, o);
        survey::NavSample n;
        n.utime_gps = sv.t0_utime + static_cast<std::int64_t>(i) * 20'000;
        n.position = world.FromEnu(v.enu);
        n.roll_rad = v.roll;
        n.pitch_rad = v.pitch;
        n.yaw_rad = v.yaw;
        n.ins_status = 3;
        sv.nav.samples.push_back(n);
        if (i % 50 == 0) {
            survey::NavStdDev sd;
            sd.utime_gps = n.utime_gps;
            sd.north_m = sd.east_m = 0.02f;
            sd.up_m = 0.03f;
            sd.roll_deg = sd.pitch_deg = 0.01f;
            sd.yaw_deg = 0.03f;
            sv.nav.stddevs.push_back(sd);
        }
    }
    const Pose T_vs = o.truth.T_vehicle_sonar();
    double fix_lat = std::nan(""), fix_lon = std::nan("");
    double next_fix = 0.0;
    for (int k = 0; k < static_cast<int>(o.duration_s * 10); ++k) {
        const double t = 0.05 + k * 0.1;  // true transmit time
        const VehicleState v = StateAt(t, o);
        const Pose T_wv = MakePose(frames::RotationWorldFromRpy(v.roll, v.pitch, v.yaw), v.enu);
        survey::PingHeader h;
        h.utime_gps =
            sv.t0_utime + std::llround((t + o.clock_error_s + o.clock_rate_ppm * 1e-6 * t) * 1e6);
        h.ping_number = k;
        h.range_resolution_m = 0.001;
        const double step = 120.0 / (o.num_beams - 1);
        h.start_angle_deg = -60;
        h.angle_increment_deg = step;
        h.beam_offset = static_cast<std::uint32_t>(sv.pings.range_counts.size());
        h.num_beams = static_cast<std::uint16_t>(o.num_beams);
        for (int b = 0; b < o.num_beams; ++b) {
            const double theta = frames::DegToRad(-60.0 + b * step);
            double lo = 0.5, hi = 60.0;
            for (int it = 0; it < 40; ++it) {
                const double r = 0.5 * (lo + hi);
                const Eigen::Vector3d p = T_wv * (T_vs * georef::BeamVectorSonar(r, theta, 0.0));
                (p.z() > Seabed(p.x(), p.y()) ? lo : hi) = r;
            }
            sv.pings.range_counts.push_back(
                static_cast<std::uint32_t>(std::lround(0.5 * (lo + hi) * 1000.0)));
        }
        if (o.header_position) {
            // A GGA fix at every whole second reaches the topside 0.15 s later.
            while (next_fix + 0.15 <= t) {
                const Geodetic g = world.FromEnu(StateAt(next_fix, o).enu);
                fix_lat = g.latitude_deg;
                fix_lon = g.longitude_deg;
                next_fix += 1.0;
            }
            h.aid_latitude_deg = fix_lat;
            h.aid_longitude_deg = fix_lon;
        }
        if (o.header_attitude) {
            // The head's sensor at 0.1 deg resolution: the vehicle's attitude through the mount.
            auto q = [](double rad) { return std::round(frames::RadToDeg(rad) * 10.0) / 10.0; };
            const frames::Rpy head = frames::RpyFromRotationWorld(T_wv.linear() * T_vs.linear());
            h.aid_roll_deg = q(head.roll);
            h.aid_pitch_deg = q(head.pitch);
            h.aid_attitude_at_ping = true;
            double hd = q(v.yaw);
            if (hd < 0) hd += 360.0;
            h.aid_heading_deg = hd;
        }
        sv.pings.pings.push_back(h);
    }
    sv.pings.clock = survey::PingClock::kTopsideHeader;
    return sv;
}

}  // namespace pitmap::proc::calib::testing
