// SPDX-License-Identifier: MIT
// The HIL rig's time base: survey time t (seconds since the survey start) <-> the host's
// monotonic clock (pacing) and its Unix wall clock (what the daemon stamps). The survey starts
// on a whole Unix second, so the receiver's GPS time is the host's GPS time.
//
// THREADING: immutable after construction; shared by every emulator thread.
#pragma once

#include <chrono>
#include <cstdint>

namespace pitmap::sim::hil {

class RealTimeBase {
public:
    // The survey starts `lead_s` (rounded up to a whole Unix second) from now.
    explicit RealTimeBase(double lead_s);

    std::int64_t start_unix_us() const { return start_unix_us_; }
    // Seconds since the survey start (negative before it), from the monotonic clock.
    double NowS() const;
    // Host Unix microseconds at survey time t.
    std::int64_t UnixAt(double t_s) const;

private:
    std::chrono::steady_clock::time_point start_steady_;
    std::int64_t start_unix_us_ = 0;
};

}  // namespace pitmap::sim::hil
