// SPDX-License-Identifier: MIT
// Bounded exponential backoff for reconnect attempts. Pure: the caller passes the times.
#pragma once

#include <algorithm>
#include <cstdint>

namespace pitmap::acq {

struct BackoffConfig {
    int initial_ms = 100;  // delay after the first failure, milliseconds (> 0)
    int max_ms = 5000;     // the delay never exceeds this, milliseconds (>= initial_ms)
    double factor = 2.0;   // growth per consecutive failure (>= 1)
};

class Backoff {
public:
    explicit Backoff(const BackoffConfig& config = {}) : config_(config) {}

    // A failure at monotonic time `now_us`: the next attempt is allowed at the returned time.
    std::int64_t Failed(std::int64_t now_us) {
        const double d = std::min<double>(
            current_ms_ == 0 ? config_.initial_ms : current_ms_ * config_.factor, config_.max_ms);
        current_ms_ = static_cast<std::int64_t>(d);
        next_attempt_us_ = now_us + current_ms_ * 1000;
        return next_attempt_us_;
    }
    // A success: the next failure starts again at initial_ms, and an attempt is allowed now.
    void Succeeded() {
        current_ms_ = 0;
        next_attempt_us_ = 0;
    }
    bool Ready(std::int64_t now_us) const { return now_us >= next_attempt_us_; }
    std::int64_t next_attempt_us() const { return next_attempt_us_; }
    std::int64_t current_delay_ms() const { return current_ms_; }

private:
    BackoffConfig config_;
    std::int64_t current_ms_ = 0;
    std::int64_t next_attempt_us_ = 0;
};

}  // namespace pitmap::acq
