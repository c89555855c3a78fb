// SPDX-License-Identifier: MIT
// What the live pages may pull: a byte budget (token bucket) per client, and the checked
// reading of the pages' query parameters (outside bytes: fuzzed by tests/fuzz/live_fuzz.cpp).
//
// ClientBudgets: the link's `rate_bytes_per_s` is shared equally among the clients seen within
// `idle_s` (a client = the peer address plus the id the page sends, budget.hpp ParseLiveQuery),
// each with its own bucket refilled at its share, at most `burst_s` seconds of its share saved
// up. So the sum of what the clients may pull stays the link rate, and a greedy client (or one
// polling often) spends only its own share: it cannot starve another. A response asks how much
// it may send (Available), builds itself to fit (fewer tiles, every k-th sounding:
// "thinning"), then spends what it sent (Spend); spending may go below zero (down to one burst
// of debt), which the next refills pay back, so a response larger than its share delays that
// client's next ones. At most `max_clients` are tracked: a new client beyond them evicts the one
// seen least recently (counted); a new or evicted-and-returning client starts with one burst.
// Memory: about 100 bytes per tracked client plus its key (<= 32 + 46 bytes).
// Thread safety: ClientBudgets is internally locked.
#pragma once

#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <string>

namespace pitmap::proc::live {

class ClientBudgets {
public:
    ClientBudgets(double rate_bytes_per_s,
                  double burst_s,
                  std::size_t max_clients = 16,
                  double idle_s = 10.0);
    // Bytes `client` may be sent now (>= 0), at `utime` (any monotonic microsecond clock).
    std::int64_t Available(const std::string& client, std::int64_t utime);
    void Spend(const std::string& client, std::int64_t bytes, std::int64_t utime);

    double rate_bytes_per_s() const { return rate_; }
    // The refill rate of each client now: the link rate over the clients active at `utime`.
    double ShareBytesPerS(std::int64_t utime) const;
    std::size_t ActiveClients(std::int64_t utime) const;
    std::size_t tracked() const;
    std::int64_t evicted() const;
    // Bytes spent in total, and by one client (0 when not tracked).
    std::int64_t spent() const;
    std::int64_t spent(const std::string& client) const;

private:
    struct Bucket {
        double tokens = 0;
        std::int64_t last_refill = 0, last_seen = 0;
        std::int64_t spent = 0;
    };
    std::size_t ActiveLocked(std::int64_t utime) const;
    Bucket& TouchLocked(const std::string& client, std::int64_t utime);
    mutable std::mutex mutex_;
    double rate_, burst_s_;
    std::size_t max_clients_;
    std::int64_t idle_us_;
    std::map<std::string, Bucket> clients_;
    std::int64_t spent_ = 0, evicted_ = 0;
};

// Whether a peer address (as the server gives it: "127.0.0.1", "::1", "::ffff:127.0.0.2") is
// this machine's loopback: a page there does not share the radio link, so by default it is not
// budgeted (ServerConfig::budget_loopback).
bool IsLoopbackAddress(const std::string& ip);

// The parameters of the page's requests, checked. Unknown keys are ignored; a known key with a
// bad value is an error naming it.
struct LiveQuery {
    std::uint64_t since = 0;      // tiles / soundings newer than this version or sequence
    std::int64_t max_bytes = -1;  // the client's own cap, -1 = none
    std::string client;  // the page's id, "" = none; 1..kMaxClientIdLength of [A-Za-z0-9_-]
    std::string error;   // non-empty: refuse the request (HTTP 400) with this text
};
inline constexpr std::size_t kMaxClientIdLength = 32;
// Parses values of `since` (0..2^63-1) and `max_bytes` (0..2^31-1), decimal digits only, and
// `client` (1..32 characters of A-Z a-z 0-9 _ -).
LiveQuery ParseLiveQuery(const std::multimap<std::string, std::string>& params);
// A decimal unsigned integer of at most `max`, digits only (no sign, no spaces); nullopt else.
std::optional<std::uint64_t> ParseDecimal(const std::string& text, std::uint64_t max);

}  // namespace pitmap::proc::live
