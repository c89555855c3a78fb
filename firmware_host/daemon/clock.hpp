// SPDX-License-Identifier: MIT
// Clock: the daemon's injected view of time, so tests drive channels with a fake clock.
//
// THREADING: SystemClock is stateless. ManualClock's time is an atomic: any thread may read
// or advance it.
#pragma once

#include <atomic>
#include <cstdint>

namespace pitmap::acq {

class Clock {
public:
    virtual ~Clock() = default;
    // Host wall clock, Unix microseconds (CLOCK_REALTIME).
    virtual std::int64_t NowUtime() const = 0;
    // Monotonic microseconds, for timeouts and ages.
    virtual std::int64_t MonotonicUs() const = 0;
};

// The real clocks (io/byte_source.hpp HostNowUtime / MonotonicNowUs).
class SystemClock final : public Clock {
public:
    std::int64_t NowUtime() const override;
    std::int64_t MonotonicUs() const override;
};

// A clock that moves only when told; wall = monotonic + a fixed epoch.
class ManualClock final : public Clock {
public:
    explicit ManualClock(std::int64_t start_utime = 1'700'000'000'000'000) : epoch_(start_utime) {}
    std::int64_t NowUtime() const override { return epoch_ + mono_.load(); }
    std::int64_t MonotonicUs() const override { return mono_.load(); }
    void AdvanceUs(std::int64_t us) { mono_.fetch_add(us); }

private:
    const std::int64_t epoch_;
    std::atomic<std::int64_t> mono_{0};
};

}  // namespace pitmap::acq
