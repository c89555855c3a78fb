// SPDX-License-Identifier: MIT
#include "processor/live/budget.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace pitmap::proc::live {

ClientBudgets::ClientBudgets(double rate_bytes_per_s,
                             double burst_s,
                             std::size_t max_clients,
                             double idle_s)
    : rate_(rate_bytes_per_s),
      burst_s_(burst_s),
      max_clients_(std::max<std::size_t>(1, max_clients)),
      idle_us_(static_cast<std::int64_t>(idle_s * 1e6)) {}

std::size_t ClientBudgets::ActiveLocked(std::int64_t utime) const {
    std::size_t n = 0;
    for (const auto& [key, b] : clients_) n += utime - b.last_seen <= idle_us_ ? 1 : 0;
    return std::max<std::size_t>(n, 1);
}

ClientBudgets::Bucket& ClientBudgets::TouchLocked(const std::string& client, std::int64_t utime) {
    auto it = clients_.find(client);
    if (it == clients_.end()) {
        if (clients_.size() >= max_clients_) {
            auto oldest = clients_.begin();
            for (auto c = clients_.begin(); c != clients_.end(); ++c) {
                if (c->second.last_seen < oldest->second.last_seen) oldest = c;
            }
            clients_.erase(oldest);
            ++evicted_;
        }
        Bucket b;
        b.last_refill = b.last_seen = utime;
        it = clients_.emplace(client, b).first;
        // One burst of the share it has now that it counts.
        it->second.tokens = rate_ / static_cast<double>(ActiveLocked(utime)) * burst_s_;
    }
    Bucket& b = it->second;
    // The share at this moment applies since the last refill (clients come and go slowly
    // against the refills, which happen at every request).
    const double share = rate_ / static_cast<double>(ActiveLocked(utime));
    if (utime > b.last_refill) {
        b.tokens = std::min(share * burst_s_,
                            b.tokens + share * static_cast<double>(utime - b.last_refill) * 1e-6);
        b.last_refill = utime;
    }
    b.last_seen = std::max(b.last_seen, utime);
    return b;
}

std::int64_t ClientBudgets::Available(const std::string& client, std::int64_t utime) {
    std::lock_guard<std::mutex> lock(mutex_);
    const Bucket& b = TouchLocked(client, utime);
    return b.tokens > 0 ? static_cast<std::int64_t>(b.tokens) : 0;
}

void ClientBudgets::Spend(const std::string& client, std::int64_t bytes, std::int64_t utime) {
    std::lock_guard<std::mutex> lock(mutex_);
    Bucket& b = TouchLocked(client, utime);
    const double share = rate_ / static_cast<double>(ActiveLocked(utime));
    b.tokens -= static_cast<double>(bytes);
    // Debt is capped at one burst, so one huge response cannot silence the page for long.
    b.tokens = std::max(b.tokens, -share * burst_s_);
    b.spent += bytes;
    spent_ += bytes;
}

double ClientBudgets::ShareBytesPerS(std::int64_t utime) const {
    std::lock_guard<std::mutex> lock(mutex_);
    return rate_ / static_cast<double>(ActiveLocked(utime));
}

std::size_t ClientBudgets::ActiveClients(std::int64_t utime) const {
    std::lock_guard<std::mutex> lock(mutex_);
    std::size_t n = 0;
    for (const auto& [key, b] : clients_) n += utime - b.last_seen <= idle_us_ ? 1 : 0;
    return n;
}

std::size_t ClientBudgets::tracked() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return clients_.size();
}

std::int64_t ClientBudgets::evicted() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return evicted_;
}

std::int64_t ClientBudgets::spent() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return spent_;
}

std::int64_t ClientBudgets::spent(const std::string& client) const {
    std::lock_guard<std::mutex> lock(mutex_);
    auto it = clients_.find(client);
    return it == clients_.end() ? 0 : it->second.spent;
}

std::optional<std::uint64_t> ParseDecimal(const std::string& text, std::uint64_t max) {
    if (text.empty() || text.size() > 20) return std::nullopt;
    std::uint64_t v = 0;
    for (char c : text) {
        if (c < '0' || c > '9') return std::nullopt;
        const auto d = static_cast<std::uint64_t>(c - '0');
        if (v > (max - d) / 10) return std::nullopt;
        v = v * 10 + d;
    }
    return v;
}

LiveQuery ParseLiveQuery(const std::multimap<std::string, std::string>& params) {
    LiveQuery q;
    for (const auto& [key, value] : params) {
        if (key == "since") {
            auto v = ParseDecimal(value, static_cast<std::uint64_t>(INT64_MAX));
            if (!v) {
                q.error = "since must be a decimal integer in [0, 2^63)";
                return q;
            }
            q.since = *v;
        } else if (key == "max_bytes") {
            auto v = ParseDecimal(value, static_cast<std::uint64_t>(INT32_MAX));
            if (!v) {
                q.error = "max_bytes must be a decimal integer in [0, 2^31)";
                return q;
            }
            q.max_bytes = static_cast<std::int64_t>(*v);
        } else if (key == "client") {
            const bool ok = !value.empty() && value.size() <= kMaxClientIdLength &&
                            std::all_of(value.begin(), value.end(), [](char c) {
                                return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') ||
                                       (c >= '0' && c <= '9') || c == '_' || c == '-';
                            });
            if (!ok) {
                q.error = "client must be 1 to 32 characters of A-Z a-z 0-9 _ -";
                return q;
            }
            q.client = value;
        }
    }
    return q;
}

bool IsLoopbackAddress(const std::string& ip) {
    // 127.0.0.0/8, also as an IPv4-mapped IPv6 address, and ::1 (RFC 1122 3.2.1.3, RFC 4291
    // 2.5.3 and 2.5.5.2).
    const auto v4_loopback = [](const std::string& a) {
        if (a.rfind("127.", 0) != 0) return false;
        int dots = 0;
        for (char c : a) {
            if (c == '.') {
                ++dots;
            } else if (c < '0' || c > '9') {
                return false;
            }
        }
        return dots == 3;
    };
    if (v4_loopback(ip)) return true;
    if (ip == "::1" || ip == "0:0:0:0:0:0:0:1") return true;
    for (const char* prefix : {"::ffff:", "::FFFF:"}) {
        if (ip.rfind(prefix, 0) == 0) return v4_loopback(ip.substr(7));
    }
    return false;
}

}  // namespace pitmap::proc::live
