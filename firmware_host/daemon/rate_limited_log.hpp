// SPDX-License-Identifier: MIT
// RateLimitedLog: human log lines to stderr (journald picks them up under systemd), at most
// one per second per condition key; suppressed repeats are counted and reported with the
// next line of that key.
//
// THREADING: Log() may be called from any thread (one mutex).
#pragma once

#include <cstdint>
#include <cstdio>
#include <map>
#include <mutex>
#include <string>

namespace pitmap::acq {

class RateLimitedLog {
public:
    // `sink` defaults to stderr; `min_interval_us` between two lines of one key.
    explicit RateLimitedLog(std::FILE* sink = stderr, std::int64_t min_interval_us = 1'000'000)
        : sink_(sink), min_interval_us_(min_interval_us) {}

    // Prints "pitmap-acqd: <message>" unless `key` printed less than min_interval_us ago
    // (by `now_us`, any monotonic clock). Returns whether it printed.
    bool Log(const std::string& key, std::int64_t now_us, const std::string& message);
    std::int64_t suppressed_total() const;

private:
    struct Entry {
        std::int64_t last_us = 0;
        std::int64_t suppressed = 0;
    };
    std::FILE* sink_;
    const std::int64_t min_interval_us_;
    mutable std::mutex mu_;
    std::map<std::string, Entry> entries_;
    std::int64_t suppressed_total_ = 0;
};

}  // namespace pitmap::acq
