// SPDX-License-Identifier: MIT
// TimeKeeper: the daemon's two clock models (host -> GPS from NovAtel arrivals, 83P header
// clock -> GPS) shared by all channels, and their clock_sync_t form. The models and the ping
// stamping rule live in common/clock, where the shore's re-decoding uses the same ones.
//
// THREADING: every method may be called from any thread (one mutex around both models).
#pragma once

#include <cstdint>
#include <mutex>

#include "common/clock/clock_model.hpp"
#include "common/clock/ping_time.hpp"
#include "common/protocol/deltat/messages.hpp"
#include "pitmap/clock_sync_t.hpp"

namespace pitmap::acq {

// The daemon's names for the shared models (common/clock).
using clock::ChunkTimes;
using clock::ClockModelConfig;
using clock::ClockQuality;
using clock::ClockState;
using clock::EnvelopeLine;
using clock::GpsEstimate;
using clock::HostClockConfig;
using clock::HostClockModel;
using clock::JumpGuardedEnvelope;
using clock::LowerEnvelope;
using clock::LowerEnvelopeConfig;
using clock::PingStamper;
using clock::PingTime;
using clock::SonarClockConfig;
using clock::SonarClockModel;
using clock::SonarPingTimes;
using clock::SonarStamp;
using clock::SonarStampMethod;
using clock::ToString;

class TimeKeeper {
public:
    explicit TimeKeeper(const HostClockConfig& host = {}, const SonarClockConfig& sonar = {});

    void AddNovatel(std::int64_t utime_host, std::int64_t utime_gps, bool time_valid);
    // An RFC 2783 PPS assert time (host Unix us); see HostClockModel::AddPps. Returns whether
    // the pulse was used.
    bool AddPps(std::int64_t utime_host);
    GpsEstimate HostToGps(std::int64_t utime_host) const;
    // Stamps one 83P ping (common/clock/ping_time.hpp): `chunk` holds the receive times of
    // the chunk that completed it, with utime_gps = HostToGps(utime_host) as logged in its
    // raw_bytes_t, so that re-decoding the log on shore gives the same time.
    PingTime StampPing(const protocol::deltat::Ping83P& ping, const ChunkTimes& chunk);

    ClockQuality HostQuality(std::int64_t utime_host_now) const;
    ClockQuality SonarQuality(std::int64_t utime_host_now) const;
    // clock_sync_t of each model at host time `utime_now`.
    pitmap::clock_sync_t HostClockSync(std::int64_t utime_now) const;
    pitmap::clock_sync_t SonarClockSync(std::int64_t utime_now) const;

private:
    mutable std::mutex mu_;
    HostClockModel host_;
    PingStamper sonar_;
    std::int64_t last_header_utime_ = 0;  // newest header time seen, for the sonar quality
    std::int64_t last_header_host_ = 0;   // host time it arrived
};

pitmap::clock_sync_t ToClockSync(const ClockQuality& q, std::int8_t source, std::int64_t utime);

}  // namespace pitmap::acq
