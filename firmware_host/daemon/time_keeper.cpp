// SPDX-License-Identifier: MIT
#include "firmware_host/daemon/time_keeper.hpp"

#include "common/gps_time.hpp"

namespace pitmap::acq {

TimeKeeper::TimeKeeper(const HostClockConfig& host, const SonarClockConfig& sonar)
    : host_(host), sonar_(sonar) {}

void TimeKeeper::AddNovatel(std::int64_t utime_host, std::int64_t utime_gps, bool time_valid) {
    std::lock_guard<std::mutex> lock(mu_);
    host_.AddMessage(utime_host, utime_gps, time_valid);
}

bool TimeKeeper::AddPps(std::int64_t utime_host) {
    std::lock_guard<std::mutex> lock(mu_);
    return host_.AddPps(utime_host);
}

GpsEstimate TimeKeeper::HostToGps(std::int64_t utime_host) const {
    std::lock_guard<std::mutex> lock(mu_);
    return host_.ToGps(utime_host);
}

PingTime TimeKeeper::StampPing(const protocol::deltat::Ping83P& ping, const ChunkTimes& chunk) {
    std::lock_guard<std::mutex> lock(mu_);
    const std::int64_t utime_header = clock::ClockInputsOf(ping).utime_header;
    if (utime_header != 0) {
        last_header_utime_ = utime_header;
        last_header_host_ = clock::ReceiveUtimeHost(chunk);
    }
    return sonar_.Stamp(ping, clock::ReceiveUtimeGps(chunk));
}

ClockQuality TimeKeeper::HostQuality(std::int64_t utime_host_now) const {
    std::lock_guard<std::mutex> lock(mu_);
    return host_.Quality(utime_host_now);
}

ClockQuality TimeKeeper::SonarQuality(std::int64_t utime_host_now) const {
    std::lock_guard<std::mutex> lock(mu_);
    // The sonar model runs on the header clock: estimate "now" on it from the last record.
    const std::int64_t header_now =
        last_header_utime_ == 0 ? 0 : last_header_utime_ + (utime_host_now - last_header_host_);
    return sonar_.model().Quality(header_now);
}

pitmap::clock_sync_t ToClockSync(const ClockQuality& q, std::int8_t source, std::int64_t utime) {
    pitmap::clock_sync_t s;
    s.utime = utime;
    s.source = source;
    s.state = static_cast<std::int8_t>(q.state);
    s.ref_utime_in = q.ref_utime_in;
    s.offset_us = q.offset_us;
    s.drift_ppm = q.drift_ppm;
    s.residual_rms_us = q.residual_rms_us;
    s.offset_stddev_us = q.offset_stddev_us;
    s.num_samples = q.num_samples;
    s.last_sample_utime = q.last_sample_utime;
    s.resets = q.resets;
    s.leap_seconds = static_cast<std::int16_t>(LeapSecondsAtUnix(utime));
    return s;
}

pitmap::clock_sync_t TimeKeeper::HostClockSync(std::int64_t utime_now) const {
    const ClockQuality q = HostQuality(utime_now);
    return ToClockSync(q,
                       q.from_pps ? pitmap::clock_sync_t::SOURCE_HOST_FROM_PPS
                                  : pitmap::clock_sync_t::SOURCE_HOST_FROM_NOVATEL,
                       utime_now);
}

pitmap::clock_sync_t TimeKeeper::SonarClockSync(std::int64_t utime_now) const {
    return ToClockSync(
        SonarQuality(utime_now), pitmap::clock_sync_t::SOURCE_SONAR_HEADER, utime_now);
}

}  // namespace pitmap::acq
