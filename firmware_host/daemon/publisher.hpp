// SPDX-License-Identifier: MIT
// Publisher: where every message of the daemon goes. The real one (LcmPublisher) hands each
// event to the daemon's LogWriter at once (LogWriter::Enqueue never blocks on disk) and to a
// bounded outbound queue that one thread drains into lcm::LCM::publish, so reader threads
// never block on LCM. A full queue drops the LCM copy and counts it; the log copy is dropped
// only by the LogWriter's own bounds (counted there).
//
// THREADING: Publish() and stats() may be called from any thread. Start()/Stop() from one
// controlling thread, idempotent. The publish thread owns the lcm::LCM object; queue_mu_
// guards the queue and the counters.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "common/result.hpp"

namespace lcm {
class LCM;
}

namespace pitmap::acq {

class LogWriter;

class Publisher {
public:
    virtual ~Publisher() = default;
    // Queues one encoded LCM message on `channel`, host time `utime`. Never blocks on I/O.
    // False when any copy was dropped (queue full, not running).
    virtual bool Publish(std::string_view channel,
                         std::int64_t utime,
                         std::vector<std::uint8_t> data) = 0;
};

struct LcmPublisherConfig {
    std::string lcm_url;                      // lcm::LCM provider URL; "" = log only, no LCM
    std::size_t queue_max_events = 20'000;    // outbound LCM queue bound, events
    std::size_t queue_max_bytes = 32u << 20;  // outbound LCM queue bound, bytes

    std::vector<std::string> Validate() const;
};

struct PublisherStats {
    std::int64_t published = 0;         // handed to lcm publish successfully
    std::int64_t publish_failures = 0;  // lcm publish returned an error
    std::int64_t queue_drops = 0;       // LCM copies dropped: queue full / not running
    std::int64_t log_drops = 0;         // LogWriter::Enqueue refused
    std::int64_t queued = 0;            // currently in the outbound queue
};

class LcmPublisher final : public Publisher {
public:
    // `log` may be null (no log). Precondition: config.Validate() is empty.
    LcmPublisher(LcmPublisherConfig config, LogWriter* log);
    ~LcmPublisher() override;

    // Creates the LCM object and the publish thread. Fails when the URL does not give a good
    // lcm::LCM. Idempotent.
    Status Start();
    // Publishes what is queued, then stops. Idempotent.
    void Stop();

    bool Publish(std::string_view channel,
                 std::int64_t utime,
                 std::vector<std::uint8_t> data) override;
    PublisherStats stats() const;
    // The LCM object (for in-process subscribers in tests, memq://); null before Start().
    lcm::LCM* lcm() { return lcm_.get(); }
    // Waits until the outbound queue is empty (bounded); false on timeout.
    bool Drain(int timeout_ms);

private:
    struct Event {
        std::string channel;
        std::vector<std::uint8_t> data;
    };
    void Run();

    const LcmPublisherConfig config_;
    LogWriter* log_;
    std::unique_ptr<lcm::LCM> lcm_;

    mutable std::mutex queue_mu_;
    std::condition_variable queue_cv_;
    std::condition_variable drained_cv_;
    std::deque<Event> queue_;
    std::size_t queue_bytes_ = 0;
    bool running_ = false;
    bool stop_requested_ = false;
    bool busy_ = false;  // the thread holds an event outside the queue
    PublisherStats stats_;
    std::thread thread_;
};

// A Publisher that keeps every event in memory, for tests and tools.
class RecordingPublisher final : public Publisher {
public:
    struct Event {
        std::string channel;
        std::int64_t utime = 0;
        std::vector<std::uint8_t> data;
    };
    bool Publish(std::string_view channel,
                 std::int64_t utime,
                 std::vector<std::uint8_t> data) override;
    std::vector<Event> events() const;
    void Clear();

private:
    mutable std::mutex mu_;
    std::vector<Event> events_;
};

}  // namespace pitmap::acq
