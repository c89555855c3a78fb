// SPDX-License-Identifier: MIT
// Real-time Delta T topside for the HIL rig: ray-casts each ping (SonarModel), encodes it as
// the topside program does (SimulatedTopside, one 83P record) and sends one UDP datagram per
// ping to the daemon, at the ping's send time plus an optional transport jitter, paced on the
// monotonic clock (shared/specs/imagenex_deltat.md §3.2). EC frames the daemon sends back to
// the datagrams' source port are decoded and counted; a new range applies to the following
// pings (acoustic range in the header, ranges beyond it reported as no detection).
// Every datagram (ping number, true transmit GPS time, jitter, hash) and EC frame goes to the
// Manifest.
//
// Failure model: Open() fails with a clear message when the source port is busy. A send
// error is recorded and the ping counted as not sent.
//
// THREADING: Start() runs one thread that owns the socket and the models' use; Stop() joins
// it. stats() after Stop().
#pragma once

#include <atomic>
#include <cstdint>
#include <string>
#include <thread>

#include "common/result.hpp"
#include "common/se3.hpp"
#include "tools/sim/hil/manifest.hpp"
#include "tools/sim/hil/realtime.hpp"
#include "tools/sim/receiver_sim.hpp"
#include "tools/sim/sonar_model.hpp"
#include "tools/sim/trajectory.hpp"

namespace pitmap::sim::hil {

struct TopsideConfig {
    std::string id = "deltat_udp";           // manifest source name
    std::string dest_address = "127.0.0.1";  // where the daemon listens
    int dest_port = 4040;
    int source_port = 0;   // 0 = any free port
    double jitter_ms = 0;  // extra latency, uniform in [0, jitter_ms]
    std::uint64_t seed = 1;
};

struct TopsideStats {
    std::int64_t pings = 0;  // datagrams sent
    std::int64_t send_errors = 0;
    std::int64_t ec_frames = 0;    // EC frames received and decoded
    std::int64_t ec_bad = 0;       // datagrams received that were not EC frames
    std::int64_t late_us_max = 0;  // worst lateness of a send vs its schedule
    int range_m = 0;               // acoustic range in effect at the end
};

class TopsideEmulator {
public:
    // The references must outlive the emulator.
    TopsideEmulator(TopsideConfig config,
                    const ScenarioConfig& scenario,
                    const TruthTrajectory& truth,
                    const SonarModel& sonar,
                    const Pose& T_vehicle_sonar,
                    std::int64_t start_utime_gps,
                    const RealTimeBase& time,
                    Manifest& manifest);
    ~TopsideEmulator();
    TopsideEmulator(const TopsideEmulator&) = delete;
    TopsideEmulator& operator=(const TopsideEmulator&) = delete;

    Status Open();
    // Sends the pings transmitted before survey time end_s.
    void Start(double end_s);
    void Stop();
    TopsideStats stats() const { return stats_; }

private:
    void Run(double end_s);
    void ReceiveEc(double now);

    TopsideConfig config_;
    ScenarioConfig scenario_;  // own copy: EC frames change the sonar settings
    const TruthTrajectory& truth_;
    const SonarModel& sonar_;
    Pose T_vehicle_sonar_;
    std::int64_t start_utime_gps_;
    const RealTimeBase& time_;
    Manifest& manifest_;
    TopsideStats stats_;
    int fd_ = -1;
    std::thread thread_;
    std::atomic<bool> stop_{false};
};

}  // namespace pitmap::sim::hil
