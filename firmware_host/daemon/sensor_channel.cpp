// SPDX-License-Identifier: MIT
#include "firmware_host/daemon/sensor_channel.hpp"

#include <cmath>
#include <limits>
#include <variant>

#include "common/protocol/deltat/record83p.hpp"
#include "common/protocol/novatel/commands.hpp"
#include "common/protocol/novatel/decoder.hpp"

namespace pitmap::acq {
namespace {

namespace nv = protocol::novatel;
namespace dt = protocol::deltat;

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

const char* ToString(ChannelProtocol p) {
    // The names are literals (channels.hpp): data() is NUL-terminated.
    return p == ChannelProtocol::kNovatel ? kProtocolNovatel.data() : kProtocolDeltat83P.data();
}

std::vector<std::string> SensorChannelConfig::Validate() const {
    std::vector<std::string> p;
    if (id.empty()) p.push_back("id must not be empty");
    for (char c : id) {
        if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_')) {
            p.push_back("id '" + id + "' may hold only letters, digits and '_'");
            break;
        }
    }
    if (read_timeout_ms < 1 || read_timeout_ms > 10'000)
        p.push_back("read_timeout_ms must be 1..10000");
    if (silent_timeout_ms < 1) p.push_back("silent_timeout_ms must be > 0");
    if (stale_partial_ms < 1) p.push_back("stale_partial_ms must be > 0");
    if (command_timeout_ms < 1) p.push_back("command_timeout_ms must be > 0");
    if (command_retries < 0 || command_retries > 10) p.push_back("command_retries must be 0..10");
    if (protocol != ChannelProtocol::kNovatel && !setup_commands.empty()) {
        p.push_back("setup_commands are for NovAtel channels only");
    }
    for (std::size_t i = 0; i < setup_commands.size(); ++i) {
        if (std::holds_alternative<nv::CommandError>(nv::ParseCommand(setup_commands[i]))) {
            p.push_back("setup_commands[" + std::to_string(i) + "] '" + setup_commands[i] +
                        "' is not a command pitmap-acqd can send");
        }
    }
    if (imu.imu_rate_hz < 0.0 || imu.corrimu_rate_hz < 0.0) p.push_back("IMU rates must be >= 0");
    if (ec.enabled) {
        if (protocol != ChannelProtocol::kDeltat83P) p.push_back("ec is for Delta T channels only");
        if (dt::EncodeEcFrame(ec.frame).empty()) {
            p.push_back(
                "ec settings cannot be encoded (range_m, sector_deg or num_beams not in "
                "the EC tables)");
        }
        if (ec.interval_ms < 100) p.push_back("ec.interval_ms must be >= 100");
    }
    return p;
}

SensorChannel::SensorChannel(SensorChannelConfig config,
                             ByteSource& source,
                             Publisher& publisher,
                             Clock& clock,
                             TimeKeeper& time,
                             RateLimitedLog* log)
    : config_(std::move(config)),
      source_(source),
      publisher_(publisher),
      clock_(clock),
      time_(time),
      log_(log),
      imu_(config_.imu) {
    for (const auto& line : config_.setup_commands) {
        const auto parsed = nv::ParseCommand(line);
        PITMAP_CHECK(std::holds_alternative<nv::Command>(parsed), "config not validated");
        command_lines_.push_back(nv::EncodeCommand(std::get<nv::Command>(parsed)));
    }
    command_index_ = command_lines_.size();
}

SensorChannel::~SensorChannel() {
    Stop();
}

void SensorChannel::Start() {
    if (running_) return;
    running_ = true;
    stop_ = false;
    const pitmap::Status opened = source_.Open();
    if (!opened) Note("open", config_.id + ": " + opened.error().message + " (retrying)");
    thread_ = std::thread([this] {
        while (!stop_.load() && RunOnce()) {
        }
        FlushFramer();
    });
}

void SensorChannel::Stop() {
    if (!running_) return;
    stop_ = true;
    if (thread_.joinable()) thread_.join();
    source_.Close();
    running_ = false;
}

bool SensorChannel::Note(const std::string& condition, const std::string& message) {
    if (log_ == nullptr) return false;
    return log_->Log(config_.id + ":" + condition, clock_.MonotonicUs(), message);
}

void SensorChannel::CheckKernelDrops() {
    const std::int64_t drops = source_.kernel_drops();
    const std::int64_t mono = clock_.MonotonicUs();
    if (drops != kernel_drops_checked_) {
        kernel_drops_checked_ = drops;
        stats_.Update([&](ChannelCounters& c) { c.kernel_drops = drops; });
    } else if (drops == kernel_drops_noted_ || mono - kernel_drops_note_mono_us_ < 1'000'000) {
        // Nothing new, or drops not yet noted but the last attempt was rate-limited less than
        // a second ago: try again later, so the final total of a burst is noted too.
        return;
    }
    kernel_drops_note_mono_us_ = mono;
    if (Note("kernel_drops",
             config_.id + ": the kernel dropped " + std::to_string(drops - kernel_drops_noted_) +
                 " datagram(s) since the last note, " + std::to_string(drops) +
                 " in total (socket receive buffer full: the reader is too "
                 "slow or the buffer too small)")) {
        kernel_drops_noted_ = drops;
    }
}

bool SensorChannel::RunOnce() {
    PollCommands();
    auto r = source_.Read(chunk_, config_.read_timeout_ms);
    CheckKernelDrops();
    const std::int64_t now = clock_.MonotonicUs();
    if (!r) {
        stats_.Update([&](ChannelCounters& c) {
            c.last_error = r.error().message;
            c.reconnects = source_.reconnects();
        });
        Note("transport", config_.id + ": " + r.error().message);
        return true;
    }
    switch (*r) {
        case ReadOutcome::kData:
            Process(chunk_);
            break;
        case ReadOutcome::kTimeout:
            if (last_bytes_mono_us_ >= 0 &&
                now - last_bytes_mono_us_ > std::int64_t{config_.stale_partial_ms} * 1000) {
                GiveUpPartials(protocol::SkipReason::kStale);
            }
            break;
        case ReadOutcome::kEndOfStream:
            FlushFramer();
            finished_ = true;
            return false;
    }
    PollCommands();
    return true;
}

void SensorChannel::PublishEncoded(std::string_view channel,
                                   std::int64_t utime,
                                   std::vector<std::uint8_t> data) {
    const bool ok = publisher_.Publish(channel, utime, std::move(data));
    stats_.Update([&](ChannelCounters& c) {
        ++c.published;
        if (!ok) ++c.queue_drops;
    });
    if (!ok) Note("drop", config_.id + ": outbound queue full, message dropped");
}

void SensorChannel::Process(const Chunk& chunk) {
    const GpsEstimate gps = time_.HostToGps(chunk.utime_host);
    RawBytesExtra extra{.utime_gps = gps.utime_gps,
                        .gps_time_valid = gps.state == ClockState::kLocked,
                        .peer = chunk.peer,
                        .utime_kernel = chunk.utime_kernel};
    const std::string_view proto =
        config_.protocol == ChannelProtocol::kNovatel ? kProtocolNovatel : kProtocolDeltat83P;
    if (chunk.foreign) {
        // Evidence of who is talking to the port, under a protocol name no decoder takes.
        const std::string foreign = std::string(proto) + std::string(kForeignSuffix);
        PublishEncoded(ChannelName(kChannelRaw, config_.id),
                       chunk.utime_host,
                       EncodeLcm(MakeRawBytes(chunk.utime_host,
                                              config_.id,
                                              foreign,
                                              source_.transport(),
                                              seq_++,
                                              std::span<const std::byte>(chunk.data),
                                              extra)));
        stats_.Update([](ChannelCounters& c) { ++c.foreign_datagrams; });
        Note("foreign",
             config_.id + ": datagram from " + chunk.peer +
                 ", not an allowed sender: logged raw as " + foreign + ", not decoded");
        return;
    }
    const std::int64_t mono = clock_.MonotonicUs();
    last_bytes_mono_us_ = mono;
    // The pings this chunk completes take their receive time from this logged value, never
    // from a later query of the host model, so that the shore re-decodes the same times.
    chunk_utime_gps_ = gps.utime_gps;
    PublishEncoded(ChannelName(kChannelRaw, config_.id),
                   chunk.utime_host,
                   EncodeLcm(MakeRawBytes(chunk.utime_host,
                                          config_.id,
                                          proto,
                                          source_.transport(),
                                          seq_++,
                                          std::span<const std::byte>(chunk.data),
                                          extra)));
    stats_.Update([&](ChannelCounters& c) {
        c.bytes += static_cast<std::int64_t>(chunk.data.size());
        ++c.chunks;
        c.last_bytes_mono_us = mono;
        c.reconnects = source_.reconnects();
    });
    if (config_.protocol == ChannelProtocol::kNovatel) {
        ProcessNovatel(chunk);
    } else {
        ProcessDeltat(chunk);
    }
}

void SensorChannel::CountSkip(const protocol::Skipped& s) {
    stats_.Update([&](ChannelCounters& c) {
        c.skipped_bytes[static_cast<std::size_t>(s.reason)] += static_cast<std::int64_t>(s.bytes);
        if (s.reason == protocol::SkipReason::kBadCrc) ++c.crc_failures;
    });
    if (s.reason == protocol::SkipReason::kBadCrc) {
        Note("crc", config_.id + ": CRC failure at stream offset " + std::to_string(s.offset));
    }
}

void SensorChannel::FlushFramer() {
    GiveUpPartials(protocol::SkipReason::kTruncated);
}

void SensorChannel::GiveUpPartials(protocol::SkipReason why) {
    // No byte came for the maximum wait (or the stream ended): a waiting candidate with
    // complete frames behind it (every candidate, at the end) gives up its sync only, and what
    // it held is framed again. A real frame cut by the pause keeps waiting. Frames found so
    // are stamped with the last chunk's receive time; they feed no clock sample, since they
    // may have arrived earlier than that.
    const bool end = why == protocol::SkipReason::kTruncated;
    if (config_.protocol == ChannelProtocol::kNovatel) {
        while (auto s = end ? novatel_framer_.Flush() : novatel_framer_.Expire()) {
            CountSkip(*s);
            DrainNovatel(last_chunk_);
        }
    } else if (source_.transport() != Transport::kUdp) {
        while (auto s = end ? deltat_framer_.Flush() : deltat_framer_.Expire()) {
            CountSkip(*s);
            DrainDeltat(last_chunk_);
        }
    }
}

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

void SensorChannel::RememberChunk(const Chunk& chunk) {
    last_chunk_.utime_host = chunk.utime_host;
    last_chunk_.utime_kernel = chunk.utime_kernel;
    if (last_chunk_.peer != chunk.peer) last_chunk_.peer = chunk.peer;
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

pitmap::channel_status_t SensorChannel::Status() const {
    ChannelCounters c = stats_.Get();
    // The counters copy it only when bytes or errors arrive; a reconnect that has not
    // delivered anything yet must show too.
    c.reconnects = source_.reconnects();
    c.kernel_drops = source_.kernel_drops();
    const std::int64_t mono = clock_.MonotonicUs();
    std::int8_t state = pitmap::channel_status_t::STATE_STOPPED;
    switch (source_.state()) {
        case SourceState::kClosed:
        case SourceState::kFinished:
            state = pitmap::channel_status_t::STATE_STOPPED;
            break;
        case SourceState::kConnecting:
            state = pitmap::channel_status_t::STATE_CONNECTING;
            break;
        case SourceState::kDisconnected:
            state = pitmap::channel_status_t::STATE_DISCONNECTED;
            break;
        case SourceState::kOpen:
            state = (c.last_bytes_mono_us < 0 ||
                     mono - c.last_bytes_mono_us > std::int64_t{config_.silent_timeout_ms} * 1000)
                        ? pitmap::channel_status_t::STATE_SILENT
                        : pitmap::channel_status_t::STATE_RUNNING;
            break;
    }
    return ToChannelStatus(c,
                           config_.id,
                           ToString(config_.protocol),
                           static_cast<std::int8_t>(source_.transport()),
                           state,
                           clock_.NowUtime(),
                           mono);
}

}  // namespace pitmap::acq
