// SPDX-License-Identifier: MIT
// SensorChannel, Delta T side: 83P records from the sonar's stream, ping stamping, and the
// sonar's switch data (EC) commands.
#include "common/protocol/deltat/record83p.hpp"
#include "firmware_host/daemon/sensor_channel.hpp"

namespace pitmap::acq {

namespace dt = protocol::deltat;

void SensorChannel::ProcessDeltat(const Chunk& chunk) {
    const ByteSpan bytes(reinterpret_cast<const std::uint8_t*>(chunk.data.data()),
                         chunk.data.size());
    if (source_.transport() == Transport::kUdp) {
        MaybeSendEc();
        const auto r = dt::DecodeDatagramInto(bytes, float_memory_, ping_);
        if (const auto* e = std::get_if<dt::DecodeError>(&r)) {
            const bool unsupported = e->kind == dt::DecodeErrorKind::kUnsupported;
            stats_.Update([&](ChannelCounters& c) {
                if (unsupported) {
                    ++c.unsupported;
                } else {
                    ++c.decode_errors;
                }
            });
            if (!unsupported) {
                Note("decode",
                     config_.id + ": bad datagram (" + std::string(dt::ToString(e->kind)) + ")");
            }
            return;
        }
        const bool comment = std::get<dt::RecordKind>(r) == dt::RecordKind::kComment;
        const std::int64_t mono = clock_.MonotonicUs();
        stats_.Update([&](ChannelCounters& c) {
            ++c.frames;
            ++c.frame_kinds[comment ? "83P_COMMENT" : "83P"];
            c.last_frame_mono_us = mono;
        });
        if (!comment) HandlePing(ping_, chunk);
        return;
    }
    deltat_framer_.Push(bytes);
    RememberChunk(chunk);
    DrainDeltat(chunk);
}

void SensorChannel::DrainDeltat(const Chunk& chunk) {
    while (true) {
        auto ev = deltat_framer_.Next();
        if (std::holds_alternative<protocol::NeedMore>(ev)) break;
        if (const auto* s = std::get_if<protocol::Skipped>(&ev)) {
            CountSkip(*s);
            continue;
        }
        const auto& rec = std::get<dt::Record>(ev);
        const std::int64_t mono = clock_.MonotonicUs();
        stats_.Update([&](ChannelCounters& c) {
            ++c.frames;
            ++c.frame_kinds[rec.layout.comment ? "83P_COMMENT" : "83P"];
            c.last_frame_mono_us = mono;
        });
        if (rec.layout.comment) continue;
        const auto r = dt::DecodeRecord83PInto(rec.bytes, float_memory_, ping_);
        if (std::holds_alternative<dt::DecodeError>(r)) {
            stats_.Update([](ChannelCounters& c) { ++c.decode_errors; });
            continue;
        }
        HandlePing(ping_, chunk);
    }
}

void SensorChannel::HandlePing(const dt::Ping83P& ping, const Chunk& chunk) {
    // The stamping rule shared with the shore's re-decoding (common/clock/ping_time.hpp).
    const PingTime stamp = time_.StampPing(ping,
                                           ChunkTimes{.utime_host = chunk.utime_host,
                                                      .utime_gps = chunk_utime_gps_,
                                                      .utime_kernel = chunk.utime_kernel});
    const std::int64_t utime_gps = stamp.utime_gps;
    std::int8_t source = pitmap::multibeam_ping_t::TIME_SOURCE_NONE;
    float stddev_s = std::numeric_limits<float>::quiet_NaN();
    if (utime_gps != 0) {
        source = stamp.method == SonarStampMethod::kHeaderModel
                     ? pitmap::multibeam_ping_t::TIME_SOURCE_HEADER_CLOCK
                     : pitmap::multibeam_ping_t::TIME_SOURCE_RECEIVE;
        stddev_s = static_cast<float>(stamp.stddev_us * 1e-6);
    }
    PublishEncoded(ChannelName(kChannelMultibeamPing, config_.id),
                   chunk.utime_host,
                   EncodeLcm(ToLcm(ping, chunk.utime_host, utime_gps, source, stddev_s)));
}

void SensorChannel::MaybeSendEc() {
    if (!config_.ec.enabled) return;
    const std::int64_t now = clock_.MonotonicUs();
    if (last_ec_mono_us_ >= 0 &&
        now - last_ec_mono_us_ < std::int64_t{config_.ec.interval_ms} * 1000) {
        return;
    }
    last_ec_mono_us_ = now;
    const std::vector<std::uint8_t> frame = dt::EncodeEcFrame(config_.ec.frame);
    const pitmap::Status w = source_.Write(
        std::span<const std::byte>(reinterpret_cast<const std::byte*>(frame.data()), frame.size()),
        100);
    stats_.Update([&](ChannelCounters& c) {
        if (w) {
            ++c.ec_frames_sent;
        } else {
            c.last_error = w.error().message;
        }
    });
}

}  // namespace pitmap::acq
