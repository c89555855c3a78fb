// SPDX-License-Identifier: MIT
// SensorChannel, NovAtel side: framing and decoding the receiver's bytes, the host clock
// samples its logs give, and the command sequence with its responses.
#include <cmath>
#include <limits>
#include <variant>

#include "common/protocol/novatel/commands.hpp"
#include "common/protocol/novatel/decoder.hpp"
#include "firmware_host/daemon/sensor_channel.hpp"

namespace pitmap::acq {
namespace {

namespace nv = protocol::novatel;

std::string_view AsText(ByteSpan b) {
    return std::string_view(reinterpret_cast<const char*>(b.data()), b.size());
}

// First comma/semicolon/asterisk-delimited word of an ASCII frame after its sync character.
std::string FirstWord(ByteSpan b) {
    std::string_view t = AsText(b.subspan(1));
    const std::size_t end = t.find_first_of(",;*\r\n");
    return std::string(t.substr(0, end));
}

// pitmap-inspect's frame naming (tools/inspect), so counts compare with the golden files.
std::string FrameKindName(const nv::Frame& f) {
    switch (f.kind) {
        case nv::FrameKind::kLongBinary: {
            const bool response =
                f.bytes.size() > 6 && (static_cast<std::uint8_t>(f.bytes[6]) & 0x80);
            return std::to_string(f.message_id) + (response ? "R" : "");
        }
        case nv::FrameKind::kShortBinary:
            return std::to_string(f.message_id);
        case nv::FrameKind::kProprietary:
            return "P" + std::to_string(f.message_id);
        case nv::FrameKind::kAscii:
            return "#" + FirstWord(f.bytes);
        case nv::FrameKind::kShortAscii:
            return "%" + FirstWord(f.bytes);
        case nv::FrameKind::kAbbreviated: {
            std::string_view t = AsText(f.bytes.subspan(1));
            while (!t.empty() && (t.back() == '\r' || t.back() == '\n')) t.remove_suffix(1);
            if (t.substr(0, 2) == "OK") return "OK";
            if (t.substr(0, 5) == "ERROR") return "ERROR";
            return "<" + std::string(t.substr(0, t.find(' ')));
        }
        case nv::FrameKind::kPrompt:
            return "PROMPT";
        case nv::FrameKind::kNmea: {
            const std::string_view t = AsText(f.bytes);
            return std::string(t.substr(0, std::min(t.find(','), t.find('*'))));
        }
    }
    return "?";
}

bool FineTime(nv::TimeStatus s) {
    return static_cast<int>(s) >= static_cast<int>(nv::TimeStatus::kFine);
}

// The sample a decoded message gives the host clock model: (gps us, valid), or nullopt for a
// message that says nothing about time.
std::optional<std::pair<std::int64_t, bool>> ClockSample(const nv::Message& m) {
    return std::visit(
        [](const auto& msg) -> std::optional<std::pair<std::int64_t, bool>> {
            using T = std::decay_t<decltype(msg)>;
            if constexpr (std::is_same_v<T, nv::PortPrompt> || std::is_same_v<T, nv::Response>) {
                return std::nullopt;
            } else {
                const nv::Header& h = msg.header;
                if (h.kind == nv::HeaderKind::kLongBinary || h.kind == nv::HeaderKind::kAscii) {
                    if (!FineTime(h.time_status)) return std::pair<std::int64_t, bool>{0, false};
                    return std::pair<std::int64_t, bool>{h.utime_gps(), h.utime_gps() != 0};
                }
                // Short headers carry no time status: only the body time of INS/IMU logs.
                if constexpr (std::is_same_v<T, nv::InsPva> || std::is_same_v<T, nv::InsAtt> ||
                              std::is_same_v<T, nv::CorrImuData> || std::is_same_v<T, nv::RawImu>) {
                    if (msg.utime_gps() != 0) {
                        return std::pair<std::int64_t, bool>{msg.utime_gps(), true};
                    }
                }
                return std::nullopt;
            }
        },
        m);
}

}  // namespace

void SensorChannel::ProcessNovatel(const Chunk& chunk) {
    chunk_best_gps_ = 0;
    chunk_time_invalid_ = false;
    novatel_framer_.Push(
        ByteSpan(reinterpret_cast<const std::uint8_t*>(chunk.data.data()), chunk.data.size()));
    RememberChunk(chunk);
    DrainNovatel(chunk);
    // One clock sample per chunk (the receive time is shared by everything in it).
    if (chunk.utime_host > last_clock_host_) {
        if (chunk_best_gps_ != 0) {
            time_.AddNovatel(chunk.utime_host, chunk_best_gps_, true);
            last_clock_host_ = chunk.utime_host;
        } else if (chunk_time_invalid_) {
            time_.AddNovatel(chunk.utime_host, 0, false);
            last_clock_host_ = chunk.utime_host;
        }
    }
}

void SensorChannel::DrainNovatel(const Chunk& chunk) {
    while (true) {
        auto ev = novatel_framer_.Next();
        if (std::holds_alternative<protocol::NeedMore>(ev)) break;
        if (const auto* s = std::get_if<protocol::Skipped>(&ev)) {
            CountSkip(*s);
            continue;
        }
        HandleNovatelFrame(std::get<nv::Frame>(ev), chunk);
    }
}

void SensorChannel::HandleNovatelFrame(const nv::Frame& frame, const Chunk& chunk) {
    const std::string kind = FrameKindName(frame);
    const std::int64_t mono = clock_.MonotonicUs();
    stats_.Update([&](ChannelCounters& c) {
        ++c.frames;
        ++c.frame_kinds[kind];
        c.last_frame_mono_us = mono;
    });
    nv::DecodeResult result = nv::Decode(frame);
    if (std::holds_alternative<nv::DecodeError>(result)) {
        stats_.Update([](ChannelCounters& c) { ++c.decode_errors; });
        Note("decode", config_.id + ": decode error in " + kind);
        return;
    }
    if (std::holds_alternative<nv::Unsupported>(result)) {
        stats_.Update([](ChannelCounters& c) { ++c.unsupported; });
        return;
    }
    const nv::Message message = nv::ToMessage(std::move(result));
    if (auto sample = ClockSample(message)) {
        if (sample->second) {
            chunk_best_gps_ = std::max(chunk_best_gps_, sample->first);
        } else {
            chunk_time_invalid_ = true;
        }
    }
    if (const auto* r = std::get_if<nv::Response>(&message)) {
        OnResponse(*r, chunk.utime_host);
        return;
    }
    if (const auto* ic = std::get_if<nv::InsConfig>(&message)) {
        if (config_.imu.imu_type < 0) imu_.imu_type = static_cast<std::int32_t>(ic->imu_type);
        return;
    }
    if (const auto* ci = std::get_if<nv::CorrImuData>(&message)) {
        // CORRIMUDATA(S) increments span the log period: measure it when not configured.
        if (ci->header.message_id != nv::msg_id::kImuRateCorrImuS &&
            config_.imu.corrimu_rate_hz <= 0.0) {
            const std::int64_t t = ci->utime_gps();
            if (last_corrimu_gps_ != 0 && t > last_corrimu_gps_ &&
                t - last_corrimu_gps_ <= 1'000'000) {
                imu_.corrimu_rate_hz = 1e6 / static_cast<double>(t - last_corrimu_gps_);
            }
            last_corrimu_gps_ = t;
        }
    }
    if (auto enc = EncodeNovatel(message, chunk.utime_host, config_.id, imu_)) {
        PublishEncoded(enc->channel, chunk.utime_host, std::move(enc->data));
    }
}

void SensorChannel::OnResponse(const nv::Response& r, std::int64_t utime_host) {
    std::string command;
    if (command_pending_ && command_index_ < command_lines_.size()) {
        command = command_lines_[command_index_];
        while (!command.empty() && (command.back() == '\n' || command.back() == '\r')) {
            command.pop_back();
        }
        const bool ok = r.ok();
        stats_.Update([&](ChannelCounters& c) {
            if (ok) {
                ++c.commands_ok;
            } else {
                ++c.commands_refused;
                c.last_error = "receiver refused '" + command + "': " + r.text;
            }
        });
        if (!ok) Note("refused", config_.id + ": receiver refused '" + command + "': " + r.text);
        command_pending_ = false;
        ++command_index_;
        SendCurrentCommand();
    }
    PublishEncoded(ChannelName(kChannelResponse, config_.id),
                   utime_host,
                   EncodeLcm(ToLcm(r, utime_host, config_.id, command)));
}

void SensorChannel::SendCurrentCommand() {
    if (command_index_ >= command_lines_.size()) return;
    const std::string& line = command_lines_[command_index_];
    const pitmap::Status w = source_.Write(
        std::span<const std::byte>(reinterpret_cast<const std::byte*>(line.data()), line.size()),
        500);
    command_pending_ = true;
    ++command_attempts_;
    command_sent_mono_us_ = clock_.MonotonicUs();
    stats_.Update([&](ChannelCounters& c) {
        ++c.commands_sent;
        if (!w) c.last_error = w.error().message;
    });
}

void SensorChannel::PollCommands() {
    if (config_.protocol != ChannelProtocol::kNovatel || command_lines_.empty()) return;
    const std::int64_t gen = source_.generation();
    if (gen != seen_generation_ && source_.state() == SourceState::kOpen) {
        // A new connection: the receiver may have forgotten everything; start over.
        seen_generation_ = gen;
        command_index_ = 0;
        command_attempts_ = 0;
        command_pending_ = false;
        SendCurrentCommand();
        return;
    }
    if (!command_pending_) return;
    if (clock_.MonotonicUs() - command_sent_mono_us_ <
        std::int64_t{config_.command_timeout_ms} * 1000) {
        return;
    }
    if (command_attempts_ <= config_.command_retries) {
        SendCurrentCommand();
        return;
    }
    stats_.Update([](ChannelCounters& c) { ++c.commands_unanswered; });
    Note("unanswered",
         config_.id + ": no answer to '" +
             command_lines_[command_index_].substr(0, command_lines_[command_index_].size() - 2) +
             "'");
    command_pending_ = false;
    command_attempts_ = 0;
    ++command_index_;
    SendCurrentCommand();
}

}  // namespace pitmap::acq
