// SPDX-License-Identifier: MIT
#include "firmware_host/daemon/pps_channel.hpp"

#include <algorithm>
#include <chrono>

#include "firmware_host/io/byte_source.hpp"

namespace pitmap::acq {

PpsChannel::PpsChannel(PpsSource& source,
                       TimeKeeper& time,
                       int fetch_timeout_ms,
                       RateLimitedLog* log,
                       BackoffConfig reopen)
    : source_(source),
      time_(time),
      fetch_timeout_ms_(fetch_timeout_ms),
      log_(log),
      backoff_(reopen) {}

PpsChannel::~PpsChannel() {
    Stop();
}

void PpsChannel::Start() {
    if (running_) return;
    running_ = true;
    stop_ = false;
    thread_ = std::thread([this] {
        while (!stop_.load()) RunOnce();
    });
}

void PpsChannel::Stop() {
    if (!running_) return;
    stop_ = true;
    if (thread_.joinable()) thread_.join();
    source_.Close();
    open_ = false;
    running_ = false;
}

PpsCounters PpsChannel::counters() const {
    std::lock_guard<std::mutex> lock(mu_);
    return counters_;
}

void PpsChannel::Failed(const std::string& message) {
    source_.Close();
    open_ = false;
    backoff_.Failed(MonotonicNowUs());
    {
        std::lock_guard<std::mutex> lock(mu_);
        ++counters_.errors;
        counters_.last_error = message;
    }
    if (log_ != nullptr) log_->Log("pps", MonotonicNowUs(), message + " (retrying)");
}

void PpsChannel::RunOnce() {
    if (!open_) {
        const std::int64_t now = MonotonicNowUs();
        if (!backoff_.Ready(now)) {
            // Sleep towards the next attempt, never longer than one fetch wait.
            const std::int64_t wait_us = std::min<std::int64_t>(backoff_.next_attempt_us() - now,
                                                                fetch_timeout_ms_ * 1000LL);
            std::this_thread::sleep_for(std::chrono::microseconds(wait_us));
            return;
        }
        if (auto s = source_.Open(); !s) {
            Failed(s.error().message);
            return;
        }
        open_ = true;
        backoff_.Succeeded();
        std::lock_guard<std::mutex> lock(mu_);
        ++counters_.opens;
    }
    PpsPulse pulse;
    const auto r = source_.Fetch(pulse, fetch_timeout_ms_);
    if (!r) {
        Failed(r.error().message);
        return;
    }
    if (*r == PpsOutcome::kTimeout) {
        std::lock_guard<std::mutex> lock(mu_);
        ++counters_.timeouts;
        return;
    }
    const bool used = time_.AddPps(pulse.utime_assert);
    std::lock_guard<std::mutex> lock(mu_);
    ++counters_.pulses;
    ++(used ? counters_.used : counters_.rejected);
}

}  // namespace pitmap::acq
