// SPDX-License-Identifier: MIT
#include "processor/live/replay.hpp"

#include <chrono>
#include <string>
#include <thread>

#include "lcmtypes/log/lcm_log_reader.hpp"

namespace pitmap::proc::live {

namespace {

std::int64_t WallUtime() {
    return std::chrono::duration_cast<std::chrono::microseconds>(
               std::chrono::system_clock::now().time_since_epoch())
        .count();
}

}  // namespace

Expected<ReplayResult> ReplayLogs(LiveSession& session,
                                  const std::vector<std::string>& paths,
                                  double speed,
                                  const std::atomic<bool>& stop,
                                  const ReplayObserver& observer) {
    ReplayResult r;
    const auto t_start = std::chrono::steady_clock::now();
    std::int64_t first_utime = 0, last_utime = 0;
    std::string channel;
    for (const std::string& path : paths) {
        auto reader = lcmlog::LcmLogReader::Open(path);
        if (!reader) return reader.error();
        ++r.files;
        lcmlog::LcmEvent ev;
        while (!stop.load() && (*reader)->Next(ev)) {
            if (first_utime == 0) first_utime = ev.utime;
            last_utime = std::max(last_utime, ev.utime);
            if (speed > 0) {
                // Sleep until this event's turn at `speed` times the logged rate.
                const auto due =
                    t_start + std::chrono::microseconds(static_cast<std::int64_t>(
                                  static_cast<double>(ev.utime - first_utime) / speed));
                std::this_thread::sleep_until(due);
            }
            channel.assign(ev.channel);
            const std::int64_t wall = WallUtime();
            session.OnEvent(channel, ev.data.data(), ev.data.size(), wall);
            session.Tick(wall);
            if (observer) observer(channel, wall);
            ++r.events;
        }
        r.corrupt_headers += (*reader)->counts().corrupt_headers;
        r.truncated_events += (*reader)->counts().truncated_events;
    }
    session.Tick(WallUtime(), true);
    r.data_seconds = static_cast<double>(last_utime - first_utime) * 1e-6;
    r.wall_seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
    return r;
}

}  // namespace pitmap::proc::live
