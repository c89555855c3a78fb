// SPDX-License-Identifier: MIT
#include "firmware_host/daemon/channel_stats.hpp"

namespace pitmap::acq {

pitmap::channel_status_t ToChannelStatus(const ChannelCounters& c,
                                         const std::string& name,
                                         const std::string& protocol,
                                         std::int8_t transport,
                                         std::int8_t state,
                                         std::int64_t utime_now,
                                         std::int64_t mono_now_us) {
    pitmap::channel_status_t s;
    s.utime = utime_now;
    s.name = name;
    s.protocol = protocol;
    s.transport = transport;
    s.state = state;
    s.bytes = c.bytes;
    s.chunks = c.chunks;
    s.frames = c.frames;
    for (const auto& [kind, n] : c.frame_kinds) {
        s.frame_kind.push_back(kind);
        s.frame_count.push_back(n);
    }
    const std::pair<const char*, std::int64_t> extra[] = {{"CMD_SENT", c.commands_sent},
                                                          {"CMD_OK", c.commands_ok},
                                                          {"CMD_REFUSED", c.commands_refused},
                                                          {"CMD_UNANSWERED", c.commands_unanswered},
                                                          {"EC_SENT", c.ec_frames_sent}};
    for (const auto& [kind, n] : extra) {
        if (n == 0) continue;
        s.frame_kind.emplace_back(kind);
        s.frame_count.push_back(n);
    }
    s.num_frame_kinds = static_cast<std::int32_t>(s.frame_kind.size());
    s.crc_failures = c.crc_failures;
    for (std::size_t i = 0; i < protocol::kNumSkipReasons; ++i) {
        s.skip_reason.emplace_back(protocol::ToString(static_cast<protocol::SkipReason>(i)));
        s.skipped_bytes.push_back(c.skipped_bytes[i]);
    }
    s.num_skip_reasons = static_cast<std::int32_t>(s.skip_reason.size());
    s.decode_errors = c.decode_errors;
    s.unsupported = c.unsupported;
    s.reconnects = c.reconnects;
    s.queue_drops = c.queue_drops;
    s.kernel_drops = c.kernel_drops;
    s.foreign_datagrams = c.foreign_datagrams;
    s.last_message_age_ms =
        c.last_frame_mono_us < 0 ? -1 : (mono_now_us - c.last_frame_mono_us) / 1000;
    s.last_error = c.last_error;
    return s;
}

}  // namespace pitmap::acq
