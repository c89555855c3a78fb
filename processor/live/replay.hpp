// SPDX-License-Identifier: MIT
// Feeds LCM log files into a LiveSession through the same OnEvent path as a live subscription
// (shore replay and the bench without a network): events in file order, paced at `speed` times
// the logged rate (0 = as fast as possible), the session ticked as it goes.
// Thread safety: call from one thread; the session may be read concurrently.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "common/result.hpp"
#include "processor/live/session.hpp"

namespace pitmap::proc::live {

struct ReplayResult {
    std::int64_t events = 0;
    std::int64_t files = 0;
    double data_seconds = 0;  // span of the logged times
    double wall_seconds = 0;
    std::int64_t corrupt_headers = 0;  // the log reader's damage counts
    std::int64_t truncated_events = 0;
};

// Called after each event has been fed and the session ticked: the event's channel and the
// wall clock (Unix microseconds) it was fed at (the latency bench times pings with it).
using ReplayObserver = std::function<void(const std::string& channel, std::int64_t wall_utime)>;

// Stops early when `stop` becomes true. An unreadable file is an error naming it.
Expected<ReplayResult> ReplayLogs(LiveSession& session,
                                  const std::vector<std::string>& paths,
                                  double speed,
                                  const std::atomic<bool>& stop,
                                  const ReplayObserver& observer = {});

}  // namespace pitmap::proc::live
