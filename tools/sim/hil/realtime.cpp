// SPDX-License-Identifier: MIT
#include "tools/sim/hil/realtime.hpp"

#include <cmath>

namespace pitmap::sim::hil {

RealTimeBase::RealTimeBase(double lead_s) {
    const auto steady = std::chrono::steady_clock::now();
    const std::int64_t unix_now = std::chrono::duration_cast<std::chrono::microseconds>(
                                      std::chrono::system_clock::now().time_since_epoch())
                                      .count();
    const std::int64_t lead_us = std::llround(lead_s * 1e6);
    start_unix_us_ = ((unix_now + lead_us) / 1'000'000 + 1) * 1'000'000;
    start_steady_ = steady + std::chrono::microseconds(start_unix_us_ - unix_now);
}

double RealTimeBase::NowS() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_steady_).count();
}

std::int64_t RealTimeBase::UnixAt(double t_s) const {
    return start_unix_us_ + std::llround(t_s * 1e6);
}

}  // namespace pitmap::sim::hil
