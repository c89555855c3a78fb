// SPDX-License-Identifier: MIT
// ChannelStats: the counters of one SensorChannel, in channel_status_t terms, plus the
// set-up command counters.
//
// THREADING: the channel's reader thread writes, the status thread reads Snapshot(); one
// mutex, taken once per chunk by the reader.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <mutex>
#include <string>

#include "common/protocol/framing.hpp"
#include "pitmap/channel_status_t.hpp"

namespace pitmap::acq {

struct ChannelCounters {
    std::int64_t bytes = 0;
    std::int64_t chunks = 0;
    std::int64_t frames = 0;                          // framed (checksum-valid), all kinds
    std::map<std::string, std::int64_t> frame_kinds;  // "BESTPOS", "1335", "OK", "83P", ...
    std::int64_t crc_failures = 0;                    // SkipReason::kBadCrc events
    std::array<std::int64_t, protocol::kNumSkipReasons> skipped_bytes{};
    std::int64_t decode_errors = 0;
    std::int64_t unsupported = 0;
    std::int64_t reconnects = 0;
    std::int64_t queue_drops = 0;        // publish calls that dropped a copy
    std::int64_t kernel_drops = 0;       // ByteSource::kernel_drops() (UDP socket)
    std::int64_t foreign_datagrams = 0;  // UDP datagrams from senders not allowed
    std::int64_t published = 0;          // messages handed to the publisher
    std::int64_t commands_sent = 0;      // set-up commands written (with retries)
    std::int64_t commands_ok = 0;
    std::int64_t commands_refused = 0;     // answered <ERROR
    std::int64_t commands_unanswered = 0;  // no answer after the retry
    std::int64_t ec_frames_sent = 0;
    std::int64_t last_frame_mono_us = -1;  // monotonic time of the last frame, -1 never
    std::int64_t last_bytes_mono_us = -1;  // monotonic time of the last chunk, -1 never
    std::string last_error;

    std::int64_t FrameCount(const std::string& kind) const {
        auto it = frame_kinds.find(kind);
        return it == frame_kinds.end() ? 0 : it->second;
    }
    std::int64_t SkippedBytes(protocol::SkipReason r) const {
        return skipped_bytes[static_cast<std::size_t>(r)];
    }
};

class ChannelStats {
public:
    template <typename F>
    void Update(F&& f) {
        std::lock_guard<std::mutex> lock(mu_);
        f(c_);
    }
    ChannelCounters Get() const {
        std::lock_guard<std::mutex> lock(mu_);
        return c_;
    }

private:
    mutable std::mutex mu_;
    ChannelCounters c_;
};

// Counters -> channel_status_t. Command counters appear as frame kinds "CMD_SENT",
// "CMD_OK", "CMD_REFUSED", "CMD_UNANSWERED", "EC_SENT" (the lcmtype has no fields of its own).
pitmap::channel_status_t ToChannelStatus(const ChannelCounters& c,
                                         const std::string& name,
                                         const std::string& protocol,
                                         std::int8_t transport,
                                         std::int8_t state,
                                         std::int64_t utime_now,
                                         std::int64_t mono_now_us);

}  // namespace pitmap::acq
