// SPDX-License-Identifier: MIT
// How an Imagenex Delta T 83P ping gets its GPS time: the one rule that pitmap-acqd applies
// live (firmware_host/daemon/sensor_channel.cpp, MULTIBEAM_PING_<ID>.utime_gps) and the shore
// applies when it re-decodes the raw bytes (processor/io/ingest.cpp, RAW_<ID>). Both feed the
// same inputs, all of them in the log, through the same SonarClockModel, so a re-decoded ping
// gets the very time the daemon published (tests/processor/io/ping_time_replay_test.cpp).
//
// The inputs of one ping, in the order the daemon sees them:
//  1. the chunk (raw_bytes_t) whose bytes completed the record: its host receive time
//     `utime`, its GPS time `utime_gps` from the host clock model when the chunk was read
//     (0 = unknown), and its kernel receive time `utime_kernel` (0 = none);
//  2. the receive instant is the kernel time when there is one, else the host time; its GPS
//     time is utime_gps - (utime - utime_kernel) (ReceiveUtimeGps): one host-model query per
//     chunk, logged, so no later model update (another thread's NovAtel sample) can change it;
//  3. the 83P header: its clock (header_time_valid, utime_sonar_header), the v1.10 data
//     latency (header instant -> datagram sent) and ping latency (header instant -> transmit);
//  4. SonarClockModel::Update(header, receive GPS, data latency) gives the GPS time of the
//     header instant; the transmit is ping latency later.
// One PingStamper per sonar channel, fed every ping of that channel in log order.
//
// Pure: no clocks, no LCM. Not thread safe (the daemon's TimeKeeper holds it under a mutex).
#pragma once

#include <cstdint>

#include "common/clock/clock_model.hpp"
#include "common/protocol/deltat/messages.hpp"

namespace pitmap::clock {

// Receive times of one chunk of bytes, as raw_bytes_t logs them.
struct ChunkTimes {
    std::int64_t utime_host = 0;    // host receive time, Unix us (raw_bytes_t.utime)
    std::int64_t utime_gps = 0;     // utime_host in GPS us by the host model; 0 = unknown
    std::int64_t utime_kernel = 0;  // kernel receive time, Unix us; 0 = not available
};

// The host instant a ping was received: the kernel time when known, else the host time.
std::int64_t ReceiveUtimeHost(const ChunkTimes& chunk);
// That instant in GPS us (0 when the chunk has no GPS time).
std::int64_t ReceiveUtimeGps(const ChunkTimes& chunk);

// What the 83P header says about a ping's time (rule 3 above).
struct PingClockInputs {
    std::int64_t utime_header = 0;       // header clock, Unix us as if UTC; 0 = not parsable
    std::int64_t age_at_send_us = 0;     // header instant -> datagram sent (v1.10), us; 0 if
                                         // unknown
    std::int64_t transmit_after_us = 0;  // header instant -> transmit (v1.10), us; 0 if unknown
};
PingClockInputs ClockInputsOf(const protocol::deltat::Ping83P& ping);

// A ping's GPS time and where it came from.
struct PingTime {
    std::int64_t utime_gps = 0;  // GPS time of the transmit, us; 0 = unknown
    SonarStampMethod method = SonarStampMethod::kNone;
    ClockState state = ClockState::kNoTime;
    double stddev_us = 0.0;  // 1-sigma of utime_gps, us (0 when unknown)
};

// One sonar channel's stamping: the header clock model, fed ping by ping.
class PingStamper {
public:
    explicit PingStamper(const SonarClockConfig& config = {});

    // Learns from one ping and returns its time. `utime_gps_receive` is ReceiveUtimeGps of
    // the chunk that completed the record.
    PingTime Stamp(const protocol::deltat::Ping83P& ping, std::int64_t utime_gps_receive);
    const SonarClockModel& model() const { return model_; }

private:
    SonarClockModel model_;
};

}  // namespace pitmap::clock
