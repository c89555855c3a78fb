// SPDX-License-Identifier: MIT
// The simulated sensors' output as wire bytes, built with common/protocol's encoders:
//   SimulatedReceiver: a NovAtel SPAN receiver (ISA-100C fibre-optic IMU) logging INSPVASB at
//     the INS rate, RAWIMUSXB at the IMU rate, and INSPVAXB, BESTPOSB, INSSTDEVB, TIMEB at the
//     GNSS rate, INSCONFIGB once; values are the truth plus the INS error model.
//   SimulatedTopside: Imagenex's topside program turning a sonar ping into one 83P record
//     (v1.10, or v1.00 by SonarConfig::format_version), stamped with the topside PC's (offset,
//     drifting) clock, with the header fields its NMEA inputs and the head's attitude sensor
//     fill (stale GGA position, VTG speed/course, HDT heading, internal pitch/roll).
//
// Topside clock convention (also written to truth/sonar_clock.json): at t seconds after the
// survey start, offset(t) = topside_clock_offset_s + topside_clock_drift_ppm * 1e-6 * t is the
// sonar header time minus UTC; the header time is the ping's interrogation, truncated to the
// header's resolution. Hence GPS time of the interrogation = header time (read as UTC) +
// (GPS - UTC) - offset(t), and the transmit is ping_latency_ms later.
// Used by `pitmap-sim synth` (log files) and by the real-time HIL emulators.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "common/geodesy.hpp"
#include "tools/sim/nav_errors.hpp"
#include "tools/sim/scenario.hpp"
#include "tools/sim/sonar_model.hpp"
#include "tools/sim/trajectory.hpp"

namespace pitmap::sim {

// One encoded receiver log, stamped with the GPS time at which the receiver emits it.
struct EmittedFrame {
    double t_emit_s = 0;  // seconds since the survey start when the last byte left the receiver
    std::uint16_t message_id = 0;
    std::vector<std::uint8_t> bytes;
};

// Thread safety: not thread safe (it keeps the IMU noise state); one per stream.
class SimulatedReceiver {
public:
    SimulatedReceiver(const ScenarioConfig& scenario,
                      const TruthTrajectory& truth,
                      const NavErrorModel& errors,
                      std::int64_t start_utime_gps);

    // Every log the receiver emits in [t0_s, t1_s), in emission order.
    std::vector<EmittedFrame> Emit(double t0_s, double t1_s);
    static constexpr std::int32_t kImuType = 26;  // Litef ISA-100C (fibre-optic gyros)

private:
    std::vector<std::uint8_t> InsPvaS(double t) const;
    std::vector<std::uint8_t> InsPvaX(double t) const;
    std::vector<std::uint8_t> BestPos(double t) const;
    std::vector<std::uint8_t> InsStdDev(double t) const;
    std::vector<std::uint8_t> TimeLog(double t) const;
    std::vector<std::uint8_t> RawImuSX(double t);
    std::vector<std::uint8_t> InsConfig(double t) const;

    const ScenarioConfig& sc_;
    const TruthTrajectory& truth_;
    const NavErrorModel& errors_;
    std::int64_t start_utime_gps_;
    LocalTangentFrame world_;
    bool config_sent_ = false;
    std::uint64_t imu_seq_ = 0;
};

// The topside program's datagram for one ping and its timing.
struct TopsideDatagram {
    double t_transmit_s = 0;          // true transmit time, seconds since the survey start
    double t_sent_s = 0;              // when the datagram left the topside PC
    std::vector<std::uint8_t> bytes;  // one 83P record
};

// Thread safety: const methods may be called concurrently. Noise of the NMEA fixes and of the
// attitude sensor depends only on (seed, fix or ping number), so two instances write the same
// bytes for the same ping.
class SimulatedTopside {
public:
    // `truth` gives the antenna position, velocity and heading the NMEA feeds report and the
    // attitude the head's sensor measures; it must outlive this object.
    SimulatedTopside(const ScenarioConfig& scenario,
                     const TruthTrajectory& truth,
                     std::int64_t start_utime_gps);
    // Encodes `ping` (transmitted at t_transmit_s) as the topside would send it.
    TopsideDatagram Encode(const SimPing& ping, double t_transmit_s) const;

private:
    const ScenarioConfig& sc_;
    const TruthTrajectory& truth_;
    std::int64_t start_utime_gps_;
    LocalTangentFrame world_;
    Eigen::Matrix3d R_vehicle_sonar_;
};

// GPS microseconds of the survey start (scenario start_utc); fails on a malformed date.
Expected<std::int64_t> SurveyStartGps(const ScenarioConfig& scenario);

}  // namespace pitmap::sim
