// SPDX-License-Identifier: MIT
#include "common/clock/ping_time.hpp"

namespace pitmap::clock {

std::int64_t ReceiveUtimeHost(const ChunkTimes& chunk) {
    return chunk.utime_kernel != 0 ? chunk.utime_kernel : chunk.utime_host;
}

std::int64_t ReceiveUtimeGps(const ChunkTimes& chunk) {
    if (chunk.utime_gps == 0) return 0;
    // The host model is a line of slope 1 + drift (|drift| <= 1000 ppm, clock_model.hpp): over
    // the host-kernel gap (< 1 ms on a loaded host) the drift term is below a microsecond.
    return chunk.utime_gps - (chunk.utime_host - ReceiveUtimeHost(chunk));
}

PingClockInputs ClockInputsOf(const protocol::deltat::Ping83P& ping) {
    PingClockInputs in;
    in.utime_header = ping.header_time_valid ? ping.utime_sonar_header : 0;
    // v1.00 has no latencies; a non-positive one says nothing.
    in.age_at_send_us = ping.is_v110() && ping.data_latency_us > 0 ? ping.data_latency_us : 0;
    in.transmit_after_us = ping.is_v110() && ping.ping_latency_us > 0 ? ping.ping_latency_us : 0;
    return in;
}

PingStamper::PingStamper(const SonarClockConfig& config) : model_(config) {}

PingTime PingStamper::Stamp(const protocol::deltat::Ping83P& ping, std::int64_t utime_gps_receive) {
    const PingClockInputs in = ClockInputsOf(ping);
    SonarPingTimes t;
    t.utime_header = in.utime_header;
    t.utime_gps_receive = utime_gps_receive;
    t.age_at_send_us = in.age_at_send_us;
    const SonarStamp s = model_.Update(t);
    PingTime out;
    if (s.utime_gps == 0) return out;
    // The model stamps the header instant (interrogation); the transmit is ping latency later.
    out.utime_gps = s.utime_gps + in.transmit_after_us;
    out.method = s.method;
    out.state = s.state;
    out.stddev_us = s.stddev_us;
    return out;
}

}  // namespace pitmap::clock
