// SPDX-License-Identifier: MIT
#include "tools/sim/hil/topside_emulator.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <random>

#include "common/protocol/deltat/ec_frame.hpp"

namespace pitmap::sim::hil {
namespace dt = protocol::deltat;

TopsideEmulator::TopsideEmulator(TopsideConfig config,
                                 const ScenarioConfig& scenario,
                                 const TruthTrajectory& truth,
                                 const SonarModel& sonar,
                                 const Pose& T_vehicle_sonar,
                                 std::int64_t start_utime_gps,
                                 const RealTimeBase& time,
                                 Manifest& manifest)
    : config_(std::move(config)),
      scenario_(scenario),
      truth_(truth),
      sonar_(sonar),
      T_vehicle_sonar_(T_vehicle_sonar),
      start_utime_gps_(start_utime_gps),
      time_(time),
      manifest_(manifest) {
    stats_.range_m = static_cast<int>(scenario_.sonar.max_range_m);
}

TopsideEmulator::~TopsideEmulator() {
    Stop();
    if (fd_ >= 0) ::close(fd_);
}

Status TopsideEmulator::Open() {
    fd_ = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
    if (fd_ < 0) return Error{std::string("topside: socket: ") + std::strerror(errno)};
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_port = htons(static_cast<std::uint16_t>(config_.source_port));
    if (::inet_pton(AF_INET, config_.dest_address.c_str(), &addr.sin_addr) != 1) {
        return Error{"topside: '" + config_.dest_address + "' is not an IPv4 address"};
    }
    if (::bind(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) != 0) {
        return Error{"topside: cannot bind UDP " + config_.dest_address + ":" +
                     std::to_string(config_.source_port) + " (" + std::strerror(errno) +
                     "; is the port busy?)"};
    }
    return Ok{};
}

void TopsideEmulator::Start(double end_s) {
    if (thread_.joinable()) return;
    stop_ = false;
    thread_ = std::thread([this, end_s] { Run(end_s); });
}

void TopsideEmulator::Stop() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
}

void TopsideEmulator::Run(double end_s) {
    std::mt19937_64 rng(config_.seed ^ 0x70751DEull);
    std::uniform_real_distribution<double> jitter(0.0, config_.jitter_ms * 1e-3);
    sockaddr_in dest{};
    dest.sin_family = AF_INET;
    dest.sin_port = htons(static_cast<std::uint16_t>(config_.dest_port));
    ::inet_pton(AF_INET, config_.dest_address.c_str(), &dest.sin_addr);
    const double rate = scenario_.sonar.ping_rate_hz;
    for (std::int64_t k = 0; !stop_.load(); ++k) {
        const double t_tx = static_cast<double>(k) / rate;
        if (t_tx >= end_s) break;
        // Ray casting takes a few milliseconds: do it before the send time, not at it.
        SimPing ping = sonar_.Ping(truth_.PoseAt(t_tx) * T_vehicle_sonar_, k);
        const double res_m = scenario_.sonar.range_resolution_mm * 1e-3;
        for (auto& c : ping.range_counts) {
            if (static_cast<double>(c) * res_m > scenario_.sonar.max_range_m) c = 0;
        }
        const SimulatedTopside topside(scenario_, truth_, start_utime_gps_);
        TopsideDatagram d = topside.Encode(ping, t_tx);
        const double j = config_.jitter_ms > 0 ? jitter(rng) : 0.0;
        const double t_send = d.t_sent_s + j;
        // Wait for the send time, answering EC frames meanwhile (bounded by the schedule).
        while (!stop_.load()) {
            const double now = time_.NowS();
            if (now >= t_send) break;
            const double wait_s = std::min(t_send - now, 0.050);
            pollfd p{fd_, POLLIN, 0};
            const timespec ts{0, static_cast<long>(wait_s * 1e9)};
            if (::ppoll(&p, 1, &ts, nullptr) > 0) ReceiveEc(time_.NowS());
        }
        if (stop_.load()) break;
        const ssize_t n = ::sendto(fd_,
                                   d.bytes.data(),
                                   d.bytes.size(),
                                   0,
                                   reinterpret_cast<const sockaddr*>(&dest),
                                   sizeof(dest));
        const double now = time_.NowS();
        if (n != static_cast<ssize_t>(d.bytes.size())) {
            ++stats_.send_errors;
            manifest_.Write(ManifestRecord("fault", config_.id)
                                .Str("fault", "send_error")
                                .Str("error", std::strerror(errno))
                                .Int("ping", k)
                                .Num("t_s", now));
            continue;
        }
        ++stats_.pings;
        stats_.late_us_max =
            std::max(stats_.late_us_max, static_cast<std::int64_t>((now - t_send) * 1e6));
        manifest_.Write(
            ManifestRecord("datagram", config_.id)
                .Int("utime", time_.UnixAt(now))
                .Num("t_s", now)
                .Bytes(d.bytes)
                .Int("ping", k)
                .Int("utime_gps_transmit", start_utime_gps_ + std::llround(t_tx * 1e6))
                .Int("jitter_us", std::llround(j * 1e6))
                .Int("late_us", std::llround((now - t_send) * 1e6))
                .Int("range_m", static_cast<std::int64_t>(scenario_.sonar.max_range_m)));
    }
    // EC frames that answer the last pings.
    const double until = time_.NowS() + 0.3;
    while (!stop_.load() && time_.NowS() < until) {
        pollfd p{fd_, POLLIN, 0};
        if (::poll(&p, 1, 50) > 0) ReceiveEc(time_.NowS());
    }
}

void TopsideEmulator::ReceiveEc(double now) {
    std::uint8_t buf[2048];
    for (int rounds = 0; rounds < 16; ++rounds) {
        const ssize_t n = ::recv(fd_, buf, sizeof(buf), 0);
        if (n < 0) return;
        const auto decoded = dt::DecodeEcFrame(ByteSpan(buf, static_cast<std::size_t>(n)));
        const auto* ec = std::get_if<dt::EcFrame>(&decoded);
        if (ec == nullptr) {
            ++stats_.ec_bad;
            manifest_.Write(ManifestRecord("ec_bad", config_.id)
                                .Int("utime", time_.UnixAt(now))
                                .Num("t_s", now)
                                .Int("len", n));
            continue;
        }
        ++stats_.ec_frames;
        // Range is the setting the 83P header reports and that bounds detections; gains
        // change no simulated quantity and are only recorded.
        if (ec->external_control && ec->range_m > 0) {
            scenario_.sonar.max_range_m = ec->range_m;
            stats_.range_m = ec->range_m;
        }
        manifest_.Write(ManifestRecord("ec", config_.id)
                            .Int("utime", time_.UnixAt(now))
                            .Num("t_s", now)
                            .Int("range_m", ec->range_m)
                            .Int("start_gain_db", ec->start_gain_db)
                            .Int("display_gain_pct", ec->display_gain_pct));
    }
}

}  // namespace pitmap::sim::hil
