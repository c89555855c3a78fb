// SPDX-License-Identifier: MIT
// PpsChannel: feeds PPS assert times from a PpsSource (io/pps_source.hpp) into the daemon's
// TimeKeeper (HostClockModel::AddPps), which labels each pulse with the whole GPS second its
// NovAtel-fitted model puts it nearest to and, after pps_min_samples pulses, maps host time
// to GPS through the pulses instead of the message envelope (clock_sync_t source
// SOURCE_HOST_FROM_PPS). A failed device is closed and reopened with bounded backoff;
// errors go to the rate-limited human log and the counters.
//
// THREADING: Start() runs one thread that owns the source; Stop() joins it (both idempotent,
// from one controlling thread). Without Start(), tests drive RunOnce() on their own thread.
// counters() may be called from any thread.
#pragma once

#include <atomic>
#include <cstdint>
#include <mutex>
#include <string>
#include <thread>

#include "firmware_host/daemon/rate_limited_log.hpp"
#include "firmware_host/daemon/time_keeper.hpp"
#include "firmware_host/io/backoff.hpp"
#include "firmware_host/io/pps_source.hpp"

namespace pitmap::acq {

struct PpsCounters {
    std::int64_t pulses = 0;    // pulses fetched
    std::int64_t used = 0;      // accepted by the host clock model
    std::int64_t rejected = 0;  // refused: no model yet, or too far from a whole GPS second
    std::int64_t timeouts = 0;  // fetches that waited without a pulse
    std::int64_t errors = 0;    // open/fetch failures
    std::int64_t opens = 0;     // successful opens
    std::string last_error;     // "" if none
};

class PpsChannel {
public:
    // References must outlive the channel. fetch_timeout_ms bounds one wait (and Stop()).
    PpsChannel(PpsSource& source,
               TimeKeeper& time,
               int fetch_timeout_ms,
               RateLimitedLog* log = nullptr,
               BackoffConfig reopen = {});
    ~PpsChannel();
    PpsChannel(const PpsChannel&) = delete;
    PpsChannel& operator=(const PpsChannel&) = delete;

    void Start();
    void Stop();
    // One step: open if needed (respecting the backoff), fetch one pulse, feed it.
    void RunOnce();
    PpsCounters counters() const;

private:
    void Failed(const std::string& message);

    PpsSource& source_;
    TimeKeeper& time_;
    const int fetch_timeout_ms_;
    RateLimitedLog* log_;
    Backoff backoff_;
    bool open_ = false;

    mutable std::mutex mu_;
    PpsCounters counters_;
    std::thread thread_;
    std::atomic<bool> stop_{false};
    bool running_ = false;
};

}  // namespace pitmap::acq
