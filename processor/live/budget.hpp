// SPDX-License-Identifier: MIT
// What the live page may pull: a byte budget (token bucket) shared by every client, and the
// checked reading of the page's query parameters (outside bytes: fuzzed by
// tests/fuzz/live_query_fuzz.cpp).
//
// ByteBudget: `rate_bytes_per_s` refill, at most `burst_s` seconds of it saved up. A response
// asks how much it may send (Available), builds itself to fit (fewer tiles, every k-th
// sounding: "thinning"), then spends what it sent (Spend); spending may go below zero, which the
// next refills pay back, so a response larger than its share delays the next ones.
// Thread safety: ByteBudget is internally locked.
#pragma once

#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <string>

namespace pitmap::proc::live {

class ByteBudget {
public:
    ByteBudget(double rate_bytes_per_s, double burst_s);
    // Bytes that may be sent now (>= 0), at `utime` (any monotonic microsecond clock).
    std::int64_t Available(std::int64_t utime);
    void Spend(std::int64_t bytes, std::int64_t utime);
    double rate_bytes_per_s() const { return rate_; }
    // Bytes spent in total.
    std::int64_t spent() const;

private:
    void Refill(std::int64_t utime);
    mutable std::mutex mutex_;
    double rate_, burst_s_;
    double tokens_;
    std::int64_t last_utime_ = 0;
    std::int64_t spent_ = 0;
};

// The parameters of the page's requests, checked. Unknown keys are ignored; a known key with a
// bad value is an error naming it.
struct LiveQuery {
    std::uint64_t since = 0;      // tiles / soundings newer than this version or sequence
    std::int64_t max_bytes = -1;  // the client's own cap, -1 = none
    std::string error;            // non-empty: refuse the request (HTTP 400) with this text
};
// Parses values of `since` (0..2^63-1) and `max_bytes` (0..2^31-1); decimal digits only.
LiveQuery ParseLiveQuery(const std::multimap<std::string, std::string>& params);
// A decimal unsigned integer of at most `max`, digits only (no sign, no spaces); nullopt else.
std::optional<std::uint64_t> ParseDecimal(const std::string& text, std::uint64_t max);

}  // namespace pitmap::proc::live
