// SPDX-License-Identifier: MIT
#include "firmware_host/daemon/sensor_channel.hpp"

#include <cmath>
#include <limits>
#include <variant>

#include "common/protocol/deltat/record83p.hpp"
#include "common/protocol/novatel/commands.hpp"
#include "common/protocol/novatel/decoder.hpp"

namespace pitmap::acq {

namespace nv = protocol::novatel;
namespace dt = protocol::deltat;

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

void SensorChannel::RememberChunk(const Chunk& chunk) {
    last_chunk_.utime_host = chunk.utime_host;
    last_chunk_.utime_kernel = chunk.utime_kernel;
    if (last_chunk_.peer != chunk.peer) last_chunk_.peer = chunk.peer;
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
