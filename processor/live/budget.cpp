// SPDX-License-Identifier: MIT
#include "processor/live/budget.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace pitmap::proc::live {

ByteBudget::ByteBudget(double rate_bytes_per_s, double burst_s)
    : rate_(rate_bytes_per_s), burst_s_(burst_s), tokens_(rate_bytes_per_s * burst_s) {}

void ByteBudget::Refill(std::int64_t utime) {
    if (last_utime_ == 0) last_utime_ = utime;
    if (utime > last_utime_) {
        tokens_ = std::min(rate_ * burst_s_,
                           tokens_ + rate_ * static_cast<double>(utime - last_utime_) * 1e-6);
        last_utime_ = utime;
    }
}

std::int64_t ByteBudget::Available(std::int64_t utime) {
    std::lock_guard<std::mutex> lock(mutex_);
    Refill(utime);
    return tokens_ > 0 ? static_cast<std::int64_t>(tokens_) : 0;
}

void ByteBudget::Spend(std::int64_t bytes, std::int64_t utime) {
    std::lock_guard<std::mutex> lock(mutex_);
    Refill(utime);
    tokens_ -= static_cast<double>(bytes);
    // Debt is capped at one burst, so one huge response cannot silence the page for long.
    tokens_ = std::max(tokens_, -rate_ * burst_s_);
    spent_ += bytes;
}

std::int64_t ByteBudget::spent() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return spent_;
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
        }
    }
    return q;
}

}  // namespace pitmap::proc::live
