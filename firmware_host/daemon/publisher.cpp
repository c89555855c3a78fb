// SPDX-License-Identifier: MIT
#include "firmware_host/daemon/publisher.hpp"

#include <lcm/lcm-cpp.hpp>

#include <chrono>

#include "firmware_host/daemon/log_writer.hpp"

namespace pitmap::acq {

std::vector<std::string> LcmPublisherConfig::Validate() const {
    std::vector<std::string> problems;
    if (queue_max_events == 0) problems.push_back("publisher queue_max_events must be > 0");
    if (queue_max_bytes == 0) problems.push_back("publisher queue_max_bytes must be > 0");
    return problems;
}

LcmPublisher::LcmPublisher(LcmPublisherConfig config, LogWriter* log)
    : config_(std::move(config)), log_(log) {}

LcmPublisher::~LcmPublisher() {
    Stop();
}

Status LcmPublisher::Start() {
    {
        std::lock_guard<std::mutex> lock(queue_mu_);
        if (running_) return Ok{};
    }
    if (!config_.lcm_url.empty()) {
        auto l = std::make_unique<lcm::LCM>(config_.lcm_url);
        if (!l->good()) return Error{"cannot create LCM for URL '" + config_.lcm_url + "'"};
        lcm_ = std::move(l);
    }
    {
        std::lock_guard<std::mutex> lock(queue_mu_);
        running_ = true;
        stop_requested_ = false;
    }
    thread_ = std::thread([this] { Run(); });
    return Ok{};
}

void LcmPublisher::Stop() {
    {
        std::lock_guard<std::mutex> lock(queue_mu_);
        if (!running_) return;
        stop_requested_ = true;
    }
    queue_cv_.notify_all();
    if (thread_.joinable()) thread_.join();
    std::lock_guard<std::mutex> lock(queue_mu_);
    running_ = false;
}

bool LcmPublisher::Publish(std::string_view channel,
                           std::int64_t utime,
                           std::vector<std::uint8_t> data) {
    bool ok = true;
    // The log first: it never blocks, and it is what must not lose data.
    if (log_ != nullptr) {
        if (!log_->Enqueue(utime, std::string(channel), data)) {
            ok = false;
            std::lock_guard<std::mutex> lock(queue_mu_);
            ++stats_.log_drops;
        }
    }
    if (config_.lcm_url.empty()) return ok;
    {
        std::lock_guard<std::mutex> lock(queue_mu_);
        if (!running_ || stop_requested_ || queue_.size() >= config_.queue_max_events ||
            queue_bytes_ + data.size() > config_.queue_max_bytes) {
            ++stats_.queue_drops;
            return false;
        }
        queue_bytes_ += data.size();
        queue_.push_back(Event{std::string(channel), std::move(data)});
    }
    queue_cv_.notify_one();
    return ok;
}

void LcmPublisher::Run() {
    std::unique_lock<std::mutex> lock(queue_mu_);
    while (true) {
        queue_cv_.wait(lock, [this] { return stop_requested_ || !queue_.empty(); });
        if (queue_.empty()) {
            if (stop_requested_) break;
            continue;
        }
        Event e = std::move(queue_.front());
        queue_.pop_front();
        queue_bytes_ -= e.data.size();
        busy_ = true;
        lock.unlock();
        const int rc =
            lcm_ ? lcm_->publish(e.channel, e.data.data(), static_cast<unsigned int>(e.data.size()))
                 : 0;
        lock.lock();
        busy_ = false;
        if (rc == 0) {
            ++stats_.published;
        } else {
            ++stats_.publish_failures;
        }
        if (queue_.empty()) drained_cv_.notify_all();
    }
    drained_cv_.notify_all();
}

bool LcmPublisher::Drain(int timeout_ms) {
    std::unique_lock<std::mutex> lock(queue_mu_);
    return drained_cv_.wait_for(
        lock, std::chrono::milliseconds(timeout_ms), [this] { return queue_.empty() && !busy_; });
}

PublisherStats LcmPublisher::stats() const {
    std::lock_guard<std::mutex> lock(queue_mu_);
    PublisherStats s = stats_;
    s.queued = static_cast<std::int64_t>(queue_.size());
    return s;
}

bool RecordingPublisher::Publish(std::string_view channel,
                                 std::int64_t utime,
                                 std::vector<std::uint8_t> data) {
    std::lock_guard<std::mutex> lock(mu_);
    events_.push_back(Event{std::string(channel), utime, std::move(data)});
    return true;
}

std::vector<RecordingPublisher::Event> RecordingPublisher::events() const {
    std::lock_guard<std::mutex> lock(mu_);
    return events_;
}

void RecordingPublisher::Clear() {
    std::lock_guard<std::mutex> lock(mu_);
    events_.clear();
}

}  // namespace pitmap::acq
