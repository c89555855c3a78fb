// SPDX-License-Identifier: MIT
#include "firmware_host/daemon/rate_limited_log.hpp"

namespace pitmap::acq {

bool RateLimitedLog::Log(const std::string& key, std::int64_t now_us, const std::string& message) {
    std::lock_guard<std::mutex> lock(mu_);
    auto [it, inserted] = entries_.try_emplace(key);
    Entry& e = it->second;
    if (!inserted && now_us - e.last_us < min_interval_us_) {
        ++e.suppressed;
        ++suppressed_total_;
        return false;
    }
    e.last_us = now_us;
    if (sink_ != nullptr) {
        if (e.suppressed > 0) {
            std::fprintf(sink_,
                         "pitmap-acqd: %s (%lld similar suppressed)\n",
                         message.c_str(),
                         static_cast<long long>(e.suppressed));
        } else {
            std::fprintf(sink_, "pitmap-acqd: %s\n", message.c_str());
        }
        std::fflush(sink_);
    }
    e.suppressed = 0;
    return true;
}

std::int64_t RateLimitedLog::suppressed_total() const {
    std::lock_guard<std::mutex> lock(mu_);
    return suppressed_total_;
}

}  // namespace pitmap::acq
