// SPDX-License-Identifier: MIT
#include "tools/sim/receiver_sim.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>

#include "common/frames.hpp"
#include "common/gps_time.hpp"
#include "common/protocol/deltat/record83p.hpp"
#include "common/protocol/novatel/encoder.hpp"

namespace pitmap::sim {
namespace nv = protocol::novatel;
namespace dt = protocol::deltat;
namespace {

constexpr double kEarthRate = 7.2921150e-5;  // rad/s
constexpr double kGravity = 9.80665;         // m/s^2 (normal gravity is close enough here)
constexpr std::uint16_t kSwBuild = 16809;

// The reported (erroneous) navigation state at t.
struct Reported {
    Geodetic geo;  // INS reference point, ellipsoidal height
    Eigen::Vector3d velocity_enu;
    frames::Rpy rpy;  // radians
    NavError error;
};

Reported Report(const TruthTrajectory& truth,
                const NavErrorModel& errors,
                const LocalTangentFrame& world,
                double t) {
    const TruthState st = truth.StateAt(t);
    Reported r;
    r.error = errors.At(t);
    r.geo = world.FromEnu(st.T_world_vehicle.translation() + r.error.position_enu_m);
    r.velocity_enu = st.velocity_world;
    const frames::Rpy true_rpy = frames::RpyFromRotationWorld(st.T_world_vehicle.linear());
    r.rpy = {true_rpy.roll + r.error.attitude_rpy_rad.x(),
             true_rpy.pitch + r.error.attitude_rpy_rad.y(),
             frames::WrapPi(true_rpy.yaw + r.error.attitude_rpy_rad.z())};
    return r;
}

double AzimuthDeg(double yaw_rad) {
    double a = frames::RadToDeg(yaw_rad);
    if (a < 0) a += 360.0;
    return a;
}

nv::Header MakeHeader(std::uint16_t id, bool short_header, std::int64_t utime_gps) {
    nv::Header h;
    h.kind = short_header ? nv::HeaderKind::kShortBinary : nv::HeaderKind::kLongBinary;
    h.message_id = id;
    h.port_address = 0x20;  // COM1
    h.idle_time = 150;
    h.time_status = nv::TimeStatus::kFineSteering;
    const GpsWeekTow wt = WeekTowFromGpsUtime(utime_gps);
    h.gps_week = static_cast<std::uint16_t>(wt.week);
    h.gps_ms = static_cast<std::uint32_t>(wt.tow_us / 1000);
    h.sw_build = kSwBuild;
    return h;
}

std::vector<std::uint8_t> Encode(const nv::Message& m) {
    std::vector<std::uint8_t> out;
    PITMAP_CHECK(nv::EncodeBinary(m, out), "simulated NovAtel message does not encode");
    return out;
}

}  // namespace

Expected<std::int64_t> SurveyStartGps(const ScenarioConfig& sc) {
    UtcCalendar c;
    if (std::sscanf(sc.start_utc.c_str(),
                    "%d-%d-%dT%d:%d:%dZ",
                    &c.year,
                    &c.month,
                    &c.day,
                    &c.hour,
                    &c.minute,
                    &c.second) != 6) {
        return Error{"start_utc '" + sc.start_utc + "' is not YYYY-MM-DDTHH:MM:SSZ"};
    }
    auto unix_us = UnixFromUtcCalendar(c);
    if (!unix_us) return Error{"start_utc '" + sc.start_utc + "' is not a valid date"};
    return GpsFromUnix(*unix_us);
}

SimulatedReceiver::SimulatedReceiver(const ScenarioConfig& sc,
                                     const TruthTrajectory& truth,
                                     const NavErrorModel& errors,
                                     std::int64_t start_utime_gps)
    : sc_(sc),
      truth_(truth),
      errors_(errors),
      start_utime_gps_(start_utime_gps),
      world_({sc.origin_latitude_deg, sc.origin_longitude_deg, sc.origin_height_m}) {}

std::vector<EmittedFrame> SimulatedReceiver::Emit(double t0, double t1) {
    std::vector<EmittedFrame> out;
    // Logs for epochs in [t0, t1). The receiver emits each a few ms after its epoch; several
    // logs of one epoch follow each other on the port.
    auto epochs = [&](double rate, auto&& make, std::uint16_t id, double latency_s) {
        const double period = 1.0 / rate;
        for (double k = std::ceil(t0 * rate - 1e-9); k / rate < t1 - 1e-12; k += 1.0) {
            const double t = k * period;
            out.push_back({t + latency_s, id, make(t)});
        }
    };
    if (!config_sent_) {
        out.push_back({t0, nv::msg_id::kInsConfig, InsConfig(t0)});
        config_sent_ = true;
    }
    epochs(
        sc_.imu_rate_hz, [&](double t) { return RawImuSX(t); }, nv::msg_id::kRawImuSX, 0.0010);
    epochs(
        sc_.ins_rate_hz, [&](double t) { return InsPvaS(t); }, nv::msg_id::kInsPvaS, 0.0030);
    epochs(
        sc_.gnss_rate_hz, [&](double t) { return BestPos(t); }, nv::msg_id::kBestPos, 0.0120);
    epochs(
        sc_.gnss_rate_hz, [&](double t) { return InsPvaX(t); }, nv::msg_id::kInsPvaX, 0.0135);
    epochs(
        sc_.gnss_rate_hz, [&](double t) { return InsStdDev(t); }, nv::msg_id::kInsStdDev, 0.0150);
    epochs(
        sc_.gnss_rate_hz, [&](double t) { return TimeLog(t); }, nv::msg_id::kTime, 0.0160);
    std::stable_sort(out.begin(), out.end(), [](const EmittedFrame& a, const EmittedFrame& b) {
        return a.t_emit_s < b.t_emit_s;
    });
    return out;
}

std::vector<std::uint8_t> SimulatedReceiver::InsPvaS(double t) const {
    const std::int64_t ug = start_utime_gps_ + std::llround(t * 1e6);
    const Reported r = Report(truth_, errors_, world_, t);
    nv::InsPva m;
    m.header = MakeHeader(nv::msg_id::kInsPvaS, true, ug);
    const GpsWeekTow wt = WeekTowFromGpsUtime(ug);
    m.gps_week = static_cast<std::uint32_t>(wt.week);
    m.gps_seconds = wt.tow_s();
    m.latitude_deg = r.geo.latitude_deg;
    m.longitude_deg = r.geo.longitude_deg;
    m.height_ellipsoid_m = r.geo.height_m;
    m.velocity_north_mps = r.velocity_enu.y();
    m.velocity_east_mps = r.velocity_enu.x();
    m.velocity_up_mps = r.velocity_enu.z();
    m.roll_deg = frames::RadToDeg(r.rpy.roll);
    m.pitch_deg = frames::RadToDeg(r.rpy.pitch);
    m.azimuth_deg = AzimuthDeg(r.rpy.yaw);
    m.ins_status = static_cast<nv::InsStatus>(r.error.ins_status);
    return Encode(m);
}

std::vector<std::uint8_t> SimulatedReceiver::InsPvaX(double t) const {
    const std::int64_t ug = start_utime_gps_ + std::llround(t * 1e6);
    const Reported r = Report(truth_, errors_, world_, t);
    nv::InsPvaX m;
    m.header = MakeHeader(nv::msg_id::kInsPvaX, false, ug);
    m.ins_status = static_cast<nv::InsStatus>(r.error.ins_status);
    m.position_type =
        r.error.gnss_available ? nv::PositionType::kInsRtkFixed : nv::PositionType::kPropagated;
    m.latitude_deg = r.geo.latitude_deg;
    m.longitude_deg = r.geo.longitude_deg;
    m.undulation_m = static_cast<float>(sc_.geoid_undulation_m);
    m.height_msl_m = r.geo.height_m - sc_.geoid_undulation_m;
    m.velocity_north_mps = r.velocity_enu.y();
    m.velocity_east_mps = r.velocity_enu.x();
    m.velocity_up_mps = r.velocity_enu.z();
    m.roll_deg = frames::RadToDeg(r.rpy.roll);
    m.pitch_deg = frames::RadToDeg(r.rpy.pitch);
    m.azimuth_deg = AzimuthDeg(r.rpy.yaw);
    m.latitude_stddev_m = static_cast<float>(r.error.position_stddev_enu_m.y());
    m.longitude_stddev_m = static_cast<float>(r.error.position_stddev_enu_m.x());
    m.height_stddev_m = static_cast<float>(r.error.position_stddev_enu_m.z());
    m.velocity_north_stddev_mps = m.velocity_east_stddev_mps = 0.01f;
    m.velocity_up_stddev_mps = 0.01f;
    m.roll_stddev_deg = static_cast<float>(frames::RadToDeg(r.error.attitude_stddev_rpy_rad.x()));
    m.pitch_stddev_deg = static_cast<float>(frames::RadToDeg(r.error.attitude_stddev_rpy_rad.y()));
    m.azimuth_stddev_deg =
        static_cast<float>(frames::RadToDeg(r.error.attitude_stddev_rpy_rad.z()));
    m.extended_status =
        (1u << 6) | (r.error.gnss_available ? 1u : 0u);  // converged, position update
    return Encode(m);
}

std::vector<std::uint8_t> SimulatedReceiver::BestPos(double t) const {
    const std::int64_t ug = start_utime_gps_ + std::llround(t * 1e6);
    const Reported r = Report(truth_, errors_, world_, t);
    nv::BestPos m;
    m.header = MakeHeader(nv::msg_id::kBestPos, false, ug);
    m.solution_status = nv::SolutionStatus::kSolComputed;
    m.position_type =
        r.error.gnss_available ? nv::PositionType::kInsRtkFixed : nv::PositionType::kPropagated;
    m.latitude_deg = r.geo.latitude_deg;
    m.longitude_deg = r.geo.longitude_deg;
    m.undulation_m = static_cast<float>(sc_.geoid_undulation_m);
    m.height_msl_m = r.geo.height_m - sc_.geoid_undulation_m;
    m.latitude_stddev_m = static_cast<float>(r.error.position_stddev_enu_m.y());
    m.longitude_stddev_m = static_cast<float>(r.error.position_stddev_enu_m.x());
    m.height_stddev_m = static_cast<float>(r.error.position_stddev_enu_m.z());
    m.base_station_id = "ROAZ";
    m.differential_age_s = r.error.gnss_available ? 1.0f : 0.0f;
    m.num_svs_tracked = r.error.gnss_available ? 18 : 0;
    m.num_svs_in_solution = r.error.gnss_available ? 16 : 0;
    m.num_svs_l1_in_solution = m.num_svs_in_solution;
    m.num_svs_multifreq_in_solution = r.error.gnss_available ? 14 : 0;
    return Encode(m);
}

std::vector<std::uint8_t> SimulatedReceiver::InsStdDev(double t) const {
    const std::int64_t ug = start_utime_gps_ + std::llround(t * 1e6);
    const NavError e = errors_.At(t);
    nv::InsStdDev m;
    m.header = MakeHeader(nv::msg_id::kInsStdDev, false, ug);
    m.latitude_stddev_m = static_cast<float>(e.position_stddev_enu_m.y());
    m.longitude_stddev_m = static_cast<float>(e.position_stddev_enu_m.x());
    m.height_stddev_m = static_cast<float>(e.position_stddev_enu_m.z());
    m.velocity_north_stddev_mps = m.velocity_east_stddev_mps = m.velocity_up_stddev_mps = 0.01f;
    m.roll_stddev_deg = static_cast<float>(frames::RadToDeg(e.attitude_stddev_rpy_rad.x()));
    m.pitch_stddev_deg = static_cast<float>(frames::RadToDeg(e.attitude_stddev_rpy_rad.y()));
    m.azimuth_stddev_deg = static_cast<float>(frames::RadToDeg(e.attitude_stddev_rpy_rad.z()));
    m.extended_status = 1u << 6;
    return Encode(m);
}

std::vector<std::uint8_t> SimulatedReceiver::TimeLog(double t) const {
    const std::int64_t ug = start_utime_gps_ + std::llround(t * 1e6);
    nv::Time m;
    m.header = MakeHeader(nv::msg_id::kTime, false, ug);
    m.clock_model_status = nv::ClockModelStatus::kValid;
    m.receiver_clock_offset_s = 1.2e-9;
    m.receiver_clock_offset_stddev_s = 5e-9;
    const int leap = LeapSecondsAtGps(ug);
    m.utc_offset_s = -leap;
    const UtcCalendar c = UtcCalendarFromUnix(UnixFromGps(ug, leap));
    m.utc_year = static_cast<std::uint32_t>(c.year);
    m.utc_month = static_cast<std::uint8_t>(c.month);
    m.utc_day = static_cast<std::uint8_t>(c.day);
    m.utc_hour = static_cast<std::uint8_t>(c.hour);
    m.utc_minute = static_cast<std::uint8_t>(c.minute);
    m.utc_ms = static_cast<std::uint32_t>(c.second * 1000 + c.microsecond / 1000);
    m.utc_status = nv::UtcStatus::kValid;
    return Encode(m);
}

std::vector<std::uint8_t> SimulatedReceiver::RawImuSX(double t) {
    const std::int64_t ug = start_utime_gps_ + std::llround(t * 1e6);
    const double dt = 1.0 / sc_.imu_rate_hz;
    // Increments over the sample interval ending at t, evaluated at its midpoint.
    const TruthState st = truth_.StateAt(t - 0.5 * dt);
    const Eigen::Matrix3d R_wv = st.T_world_vehicle.linear();
    const double lat = frames::DegToRad(sc_.origin_latitude_deg);
    const Eigen::Vector3d earth_rate_world(
        0, kEarthRate * std::cos(lat), kEarthRate * std::sin(lat));
    const Eigen::Vector3d omega_frd = st.angular_rate_vehicle + R_wv.transpose() * earth_rate_world;
    const Eigen::Vector3d f_frd =
        R_wv.transpose() * (st.acceleration_world + Eigen::Vector3d(0, 0, kGravity));
    // IMU enclosure aligned with the SPAN frame (x right, y forward, z up).
    const Eigen::Matrix3d R_span_frd = frames::RotationVehicleFromSpan().transpose();
    const Eigen::Vector3d omega = R_span_frd * omega_frd, f = R_span_frd * f_frd;
    // Sensor noise: white, at fibre-optic gyro and navigation-grade accelerometer levels.
    std::mt19937_64 rng(sc_.seed * 0x2545F4914F6CDD1Dull + imu_seq_++);
    std::normal_distribution<double> g(0.0, 1.0);
    const auto scale = *nv::ImuScaleFor(kImuType, sc_.imu_rate_hz);
    nv::RawImu m;
    m.header = MakeHeader(nv::msg_id::kRawImuSX, true, ug);
    m.imu_type = kImuType;
    const GpsWeekTow wt = WeekTowFromGpsUtime(ug);
    m.gps_week = static_cast<std::uint32_t>(wt.week);
    m.gps_seconds = wt.tow_s();
    for (int i = 0; i < 3; ++i) {
        const double dtheta = omega[i] * dt + 2e-7 * g(rng);
        const double dv = f[i] * dt + 2e-5 * g(rng);
        m.gyro_counts[static_cast<std::size_t>(i)] =
            std::llround(dtheta / scale.gyro_rad_per_count);
        m.accel_counts[static_cast<std::size_t>(i)] = std::llround(dv / scale.accel_mps_per_count);
    }
    return Encode(m);
}

std::vector<std::uint8_t> SimulatedReceiver::InsConfig(double t) const {
    const std::int64_t ug = start_utime_gps_ + std::llround(t * 1e6);
    nv::InsConfig m;
    m.header = MakeHeader(nv::msg_id::kInsConfig, false, ug);
    m.imu_type = kImuType;
    return Encode(m);
}

namespace {

// Noise streams of the topside's inputs.
constexpr std::uint64_t kStreamGga = 1, kStreamVtg = 2, kStreamHdt = 3, kStreamAttitude = 4;
constexpr double kMpsPerKnot = 1852.0 / 3600.0;

// Two independent standard normal numbers that depend only on (seed, stream, index).
std::array<double, 2> GaussPair(std::uint64_t seed, std::uint64_t stream, std::int64_t index) {
    auto mix = [](std::uint64_t z) {
        z += 0x9E3779B97F4A7C15ull;
        z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
        z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
        return z ^ (z >> 31);
    };
    const std::uint64_t a =
        mix(seed ^ mix(stream * 0xD1B54A32D192ED03ull ^ static_cast<std::uint64_t>(index)));
    const std::uint64_t b = mix(a);
    const double u1 = (static_cast<double>(a >> 11) + 0.5) / 9007199254740992.0;  // (0, 1)
    const double u2 = static_cast<double>(b >> 11) / 9007199254740992.0;
    const double r = std::sqrt(-2.0 * std::log(u1)), phi = 2.0 * 3.14159265358979323846 * u2;
    return {r * std::cos(phi), r * std::sin(phi)};
}

// Index of the last sentence of a feed at `rate_hz` (epochs k / rate_hz, k >= 0) that has
// reached the topside at time t, `latency_s` after its epoch; -1 if none has yet.
std::int64_t LastEpoch(double rate_hz, double latency_s, double t) {
    const double x = (t - latency_s) * rate_hz;
    if (x < -1e-9) return -1;
    return static_cast<std::int64_t>(std::floor(x + 1e-9));
}

double WrapDeg360(double a) {
    a = std::fmod(a, 360.0);
    if (a < 0) a += 360.0;
    return a;
}

}  // namespace

SimulatedTopside::SimulatedTopside(const ScenarioConfig& sc,
                                   const TruthTrajectory& truth,
                                   std::int64_t start_utime_gps)
    : sc_(sc),
      truth_(truth),
      start_utime_gps_(start_utime_gps),
      world_({sc.origin_latitude_deg, sc.origin_longitude_deg, sc.origin_height_m}),
      R_vehicle_sonar_(frames::RotationNedFromRpy(frames::DegToRad(sc.boresight_deg.at(0)),
                                                  frames::DegToRad(sc.boresight_deg.at(1)),
                                                  frames::DegToRad(sc.boresight_deg.at(2)))) {}

TopsideDatagram SimulatedTopside::Encode(const SimPing& ping, double t_transmit) const {
    const SonarConfig& so = sc_.sonar;
    TopsideDatagram d;
    d.t_transmit_s = t_transmit;
    const double t_interrogate = t_transmit - so.ping_latency_ms * 1e-3;
    d.t_sent_s = t_interrogate + so.data_latency_ms * 1e-3;
    // Topside PC clock: UTC plus an offset (time zone and error) that drifts.
    const std::int64_t ug = start_utime_gps_ + std::llround(t_interrogate * 1e6);
    double clock_s = so.topside_clock_offset_s + so.topside_clock_drift_ppm * 1e-6 * t_interrogate;
    if (so.topside_clock_step_at_s >= 0 && t_interrogate >= so.topside_clock_step_at_s)
        clock_s += so.topside_clock_step_s;
    const std::int64_t header_unix = UnixFromGps(ug) + std::llround(clock_s * 1e6);

    dt::Ping83P p;
    p.format_version = static_cast<std::uint8_t>(so.format_version);
    dt::SetHeaderTime(p, header_unix);
    // Auxiliary inputs: what the topside had last received at the interrogation.
    double latitude = std::numeric_limits<double>::quiet_NaN();  // blank: no fix yet / no feed
    double longitude = std::numeric_limits<double>::quiet_NaN();
    const std::int64_t fix =
        so.nmea_position ? LastEpoch(so.nmea_position_rate_hz, so.nmea_latency_s, t_interrogate)
                         : -1;
    if (fix >= 0) {
        // GGA: the antenna position at the fix epoch. VTG: its velocity over ground.
        const double t_fix = static_cast<double>(fix) / so.nmea_position_rate_hz;
        const auto& la = sc_.lever_arms.antenna_m;
        const Eigen::Vector3d lever(la[0], la[1], la[2]);
        Eigen::Vector3d antenna = truth_.PoseAt(t_fix) * lever;
        const auto n = GaussPair(sc_.seed, kStreamGga, fix);
        antenna.x() += so.nmea_position_noise_m * n[0];
        antenna.y() += so.nmea_position_noise_m * n[1];
        const Geodetic g = world_.FromEnu(antenna);
        latitude = g.latitude_deg;
        longitude = g.longitude_deg;
        const double h = 0.05, t0 = std::max(0.0, t_fix - h), t1 = t_fix + h;
        const Eigen::Vector3d v =
            (truth_.PoseAt(t1) * lever - truth_.PoseAt(t0) * lever) / (t1 - t0);
        const auto nvel = GaussPair(sc_.seed, kStreamVtg, fix);
        const double ve = v.x() + so.nmea_speed_noise_mps * nvel[0];
        const double vn = v.y() + so.nmea_speed_noise_mps * nvel[1];
        p.speed_over_ground_knots = std::min(std::hypot(ve, vn) / kMpsPerKnot, 25.5);
        double course = WrapDeg360(frames::RadToDeg(std::atan2(ve, vn)));
        if (course >= 359.95) course -= 360.0;  // 0.1 deg field: 360.0 is written as 0.0
        p.course_over_ground_deg = course;
    }
    dt::SetHeaderLatitude(p, latitude);
    dt::SetHeaderLongitude(p, longitude);
    const std::int64_t hdt =
        so.nmea_heading && p.is_v110()
            ? LastEpoch(so.nmea_heading_rate_hz, so.nmea_latency_s, t_interrogate)
            : -1;
    if (hdt >= 0) {
        // HDT: true heading of the vehicle's x axis at the sentence's epoch.
        const double t_hdt = static_cast<double>(hdt) / so.nmea_heading_rate_hz;
        const frames::Rpy rpy = frames::RpyFromRotationWorld(truth_.PoseAt(t_hdt).linear());
        const double heading =
            WrapDeg360(frames::RadToDeg(rpy.yaw) +
                       so.nmea_heading_noise_deg * GaussPair(sc_.seed, kStreamHdt, hdt)[0]);
        p.external_sensor_flags |= dt::kExternalHeadingValid;
        p.external_heading_deg = static_cast<float>(heading);
    }
    if (so.internal_attitude_sensor) {
        // The head's own attitude (vehicle attitude composed with the mount) at the
        // interrogation; the encoder quantises to 0.1 deg.
        const Eigen::Matrix3d R_world_sonar =
            truth_.PoseAt(t_interrogate).linear() * R_vehicle_sonar_;
        const frames::Rpy rpy = frames::RpyFromRotationWorld(R_world_sonar);
        const auto n = GaussPair(sc_.seed, kStreamAttitude, ping.ping_number);
        p.internal_pitch_valid = p.internal_roll_valid = true;
        p.internal_pitch_deg = frames::RadToDeg(rpy.pitch) + so.internal_attitude_noise_deg * n[0];
        p.internal_roll_deg = frames::RadToDeg(rpy.roll) + so.internal_attitude_noise_deg * n[1];
    }
    p.samples_per_beam = 500;
    p.sector_size_deg = 120;
    p.start_angle_cdeg = static_cast<std::int32_t>(std::lround(so.start_angle_deg * 100.0));
    p.angle_increment_cdeg = static_cast<std::uint8_t>(std::lround(so.angle_increment_deg * 100.0));
    p.acoustic_range_m = static_cast<std::uint16_t>(so.max_range_m);
    p.frequency_khz = 260;
    p.sound_velocity_flag = true;
    // The speed the sonar used (with a refracting water column: the speed at the head).
    const double sv = ping.sound_speed_mps > 0 ? ping.sound_speed_mps : so.sound_speed_mps;
    p.sound_velocity_header_mps = std::round(sv * 10.0) / 10.0;  // the field's 0.1 m/s
    p.sound_velocity_mps = p.sound_velocity_header_mps;
    p.sound_velocity_valid = true;
    p.range_resolution_mm = static_cast<std::uint16_t>(std::lround(so.range_resolution_mm));
    p.repetition_rate_ms = static_cast<std::uint16_t>(std::lround(1000.0 / so.ping_rate_hz));
    p.ping_number = static_cast<std::uint32_t>(ping.ping_number);
    p.intensity_included = so.intensities && so.format_version >= 10;
    p.ping_latency_us = static_cast<std::int32_t>(std::lround(so.ping_latency_ms * 1000.0));
    p.data_latency_us = static_cast<std::int32_t>(std::lround(so.data_latency_ms * 1000.0));
    p.range_counts = ping.range_counts;
    if (p.intensity_included) p.intensities = ping.intensities;
    PITMAP_CHECK(dt::EncodeRecord83P(p, {}, d.bytes), "simulated 83P record does not encode");
    return d;
}

}  // namespace pitmap::sim
