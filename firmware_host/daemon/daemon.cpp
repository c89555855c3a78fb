// SPDX-License-Identifier: MIT
#include "firmware_host/daemon/daemon.hpp"

#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "common/gps_time.hpp"
#include "firmware_host/daemon/to_lcm.hpp"

namespace pitmap::acq {
namespace {

std::unique_ptr<ByteSource> MakeSource(const ChannelSpec& spec) {
    switch (spec.kind) {
        case SourceKind::kSerial:
            return std::make_unique<SerialSource>(spec.serial);
        case SourceKind::kTcp:
            return std::make_unique<TcpClientSource>(spec.tcp);
        case SourceKind::kUdp:
            return std::make_unique<UdpSource>(spec.udp);
        case SourceKind::kFile:
            return std::make_unique<FileSource>(spec.file);
    }
    return nullptr;
}

std::string Hostname() {
    char buf[256] = {};
    if (gethostname(buf, sizeof(buf) - 1) != 0) return "";
    return buf;
}

}  // namespace

Daemon::Daemon(DaemonConfig config, Clock& clock) : Daemon(std::move(config), clock, nullptr) {}

Daemon::Daemon(DaemonConfig config, Clock& clock, std::unique_ptr<PpsSource> pps)
    : config_(std::move(config)),
      clock_(clock),
      time_(config_.host_clock, config_.sonar_clock),
      log_(config_.log, {}, &human_log_),
      publisher_(config_.publisher, &log_) {
    for (const auto& spec : config_.channels) {
        sources_.push_back(MakeSource(spec));
        channels_.push_back(std::make_unique<SensorChannel>(
            spec.channel, *sources_.back(), publisher_, clock_, time_, &human_log_));
    }
    if (!config_.pps.device.empty()) {
        pps_source_ = pps ? std::move(pps) : std::make_unique<Rfc2783PpsSource>(config_.pps.device);
        pps_ = std::make_unique<PpsChannel>(
            *pps_source_, time_, config_.pps.fetch_timeout_ms, &human_log_);
    }
}

void Daemon::NoteUdpListening(std::size_t index) {
    // Who the channel listens to, said once at start-up (issue 14 case 10).
    const ChannelSpec& spec = config_.channels[index];
    const auto* udp = dynamic_cast<const UdpSource*>(sources_[index].get());
    if (udp == nullptr) return;
    std::string allowed;
    for (const auto& a : spec.udp.allowed_senders) allowed += (allowed.empty() ? "" : ", ") + a;
    std::string text = spec.channel.id + ": udp ";
    if (spec.udp.bind_address == "0.0.0.0") {
        text += "bound to 0.0.0.0:" + std::to_string(spec.udp.port) +
                ", EVERY interface, because bind_address: 0.0.0.0 is configured";
    } else if (!udp->bound_address().empty()) {
        text += "bound to " + udp->bound_address() + ":" + std::to_string(udp->bound_port()) +
                (spec.udp.bind_address.empty()
                     ? " (the interface facing " + spec.udp.allowed_senders.front() + ")"
                     : "");
    } else {
        text += "not bound yet (" + udp->last_error() + "; retrying)";
    }
    text += "; datagrams from " + allowed +
            " are decoded, any other sender's are logged raw "
            "as foreign";
    if (spec.channel.ec.enabled) {
        text += "; EC frames only to " +
                (spec.udp.reply_to.empty() ? spec.udp.allowed_senders.front() : spec.udp.reply_to);
    }
    human_log_.Log(spec.channel.id + ":listen", clock_.MonotonicUs(), text);
}

PpsCounters Daemon::pps_counters() const {
    return pps_ ? pps_->counters() : PpsCounters{};
}

Daemon::~Daemon() {
    Stop();
}

Status Daemon::Start() {
    if (started_) return Ok{};
    std::error_code ec;
    std::filesystem::create_directories(config_.log.directory, ec);
    std::string log_dir = config_.log.directory;
    if (ec) {
        // The log writer starts in the fallback directory if there is one (and says so).
        if (config_.log.fallback_directory.empty()) {
            return Error{"cannot create log directory " + config_.log.directory + ": " +
                         ec.message()};
        }
        log_dir = config_.log.fallback_directory;
        std::filesystem::create_directories(log_dir, ec);
    }
    if (!config_.vehicle_yaml.empty()) {
        const std::string path = log_dir + "/vehicle.yaml";
        std::ofstream out(path, std::ios::trunc);
        out << config_.vehicle_yaml;
        if (!out) return Error{"cannot write " + path};
    }
    if (auto s = log_.Start(); !s) return s;
    if (auto s = publisher_.Start(); !s) {
        log_.Stop();
        return s;
    }
    start_mono_us_ = clock_.MonotonicUs();
    for (std::size_t i = 0; i < config_.channels.size(); ++i) {
        // Opened here, before its reader thread exists, to say where it listens; a failure
        // is reported again and retried by the channel.
        if (config_.channels[i].kind != SourceKind::kUdp) continue;
        (void)sources_[i]->Open();
        NoteUdpListening(i);
    }
    for (auto& ch : channels_) ch->Start();
    if (pps_) pps_->Start();
    started_ = true;
    return Ok{};
}

pitmap::daemon_status_t Daemon::Snapshot() const {
    const std::int64_t now = clock_.NowUtime();
    pitmap::daemon_status_t s;
    s.utime = now;
    s.utime_gps = time_.HostToGps(now).utime_gps;
    s.hostname = Hostname();
    s.uptime_s = (clock_.MonotonicUs() - start_mono_us_) / 1'000'000;
    for (const auto& ch : channels_) s.channels.push_back(ch->Status());
    s.num_channels = static_cast<std::int32_t>(s.channels.size());
    s.host_clock = time_.HostClockSync(now);
    s.sonar_clock = time_.SonarClockSync(now);
    const LogWriterStats ls = log_.stats();
    s.logging = static_cast<std::int8_t>(ls.state);
    s.log_path = ls.current_path;
    s.log_bytes_written = ls.bytes_written;
    s.log_events_written = ls.events_written;
    s.log_events_dropped = ls.dropped();
    s.disk_free_bytes = ls.disk_free_bytes;
    s.publish_failures = publisher_.stats().publish_failures;
    s.log_dir_lost = ls.directory_lost;
    s.log_events_lost = ls.events_lost;
    s.log_directory = ls.directory;
    return s;
}

void Daemon::PublishStatus() {
    const pitmap::daemon_status_t s = Snapshot();
    const std::int64_t mono = clock_.MonotonicUs();
    for (const auto& cs : s.channels) {
        publisher_.Publish(ChannelName(kChannelStatus, cs.name), s.utime, EncodeLcm(cs));
        if (cs.state == pitmap::channel_status_t::STATE_DISCONNECTED ||
            cs.state == pitmap::channel_status_t::STATE_SILENT) {
            human_log_.Log(cs.name + ":state",
                           mono,
                           cs.name +
                               (cs.state == pitmap::channel_status_t::STATE_SILENT
                                    ? ": no data"
                                    : ": disconnected, reconnecting") +
                               (cs.last_error.empty() ? "" : " (" + cs.last_error + ")"));
        }
    }
    publisher_.Publish(std::string(kChannelClockSync), s.utime, EncodeLcm(s.host_clock));
    publisher_.Publish(std::string(kChannelClockSync), s.utime, EncodeLcm(s.sonar_clock));
    publisher_.Publish(std::string(kChannelDaemonStatus), s.utime, EncodeLcm(s));
    if (s.logging != pitmap::daemon_status_t::LOGGING_ON && s.log_events_written > 0) {
        human_log_.Log("log", mono, "logging stopped: " + log_.stats().last_error);
    }
}

void Daemon::Rotate() {
    log_.RequestRotate();
}

bool Daemon::AllFinished() const {
    for (const auto& ch : channels_) {
        if (!ch->finished()) return false;
    }
    return !channels_.empty();
}

void Daemon::Stop() {
    if (!started_) return;
    if (pps_) pps_->Stop();
    for (auto& ch : channels_) ch->Stop();
    PublishStatus();
    publisher_.Drain(2000);
    publisher_.Stop();
    log_.Flush(5000);
    log_.Stop();
    started_ = false;
}

}  // namespace pitmap::acq
