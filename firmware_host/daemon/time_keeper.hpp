// SPDX-License-Identifier: MIT
// TimeKeeper: the daemon's two clock models (host -> GPS from NovAtel arrivals, 83P header
// clock -> GPS) shared by all channels, and their clock_sync_t form.
//
// THREADING: every method may be called from any thread (one mutex around both models).
#pragma once

#include <cstdint>
#include <mutex>

#include "firmware_host/daemon/clock_model.hpp"
#include "pitmap/clock_sync_t.hpp"

namespace pitmap::acq {

class TimeKeeper {
public:
    explicit TimeKeeper(const HostClockConfig& host = {}, const SonarClockConfig& sonar = {});

    void AddNovatel(std::int64_t utime_host, std::int64_t utime_gps, bool time_valid);
    // An RFC 2783 PPS assert time (host Unix us); see HostClockModel::AddPps. Returns whether
    // the pulse was used.
    bool AddPps(std::int64_t utime_host);
    GpsEstimate HostToGps(std::int64_t utime_host) const;
    // Stamps one 83P record: the receive time goes through the host model first.
    SonarStamp StampPing(std::int64_t utime_receive_host,
                         std::int64_t utime_header,
                         std::int64_t age_at_send_us);

    ClockQuality HostQuality(std::int64_t utime_host_now) const;
    ClockQuality SonarQuality(std::int64_t utime_host_now) const;
    // clock_sync_t of each model at host time `utime_now`.
    pitmap::clock_sync_t HostClockSync(std::int64_t utime_now) const;
    pitmap::clock_sync_t SonarClockSync(std::int64_t utime_now) const;

private:
    mutable std::mutex mu_;
    HostClockModel host_;
    SonarClockModel sonar_;
    std::int64_t last_header_utime_ = 0;  // newest header time seen, for the sonar quality
    std::int64_t last_header_host_ = 0;   // host time it arrived
};

pitmap::clock_sync_t ToClockSync(const ClockQuality& q, std::int8_t source, std::int64_t utime);

}  // namespace pitmap::acq
