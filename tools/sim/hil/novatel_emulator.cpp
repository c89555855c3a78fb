// SPDX-License-Identifier: MIT
#include "tools/sim/hil/novatel_emulator.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <pty.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>

#include "common/protocol/novatel/commands.hpp"
#include "common/protocol/novatel/encoder.hpp"
#include "common/protocol/novatel/framer.hpp"

namespace pitmap::sim::hil {
namespace nv = protocol::novatel;
namespace {

constexpr double kGenerateAheadS = 0.3;  // frames are simulated this far ahead of time
constexpr double kGenerateBlockS = 0.1;
constexpr double kDrainLimitS = 2.0;   // after end_s: finish the line, at most this long
constexpr double kUnplugDrainS = 0.5;  // wait for the reader to empty the pty before closing
constexpr std::size_t kMaxCommandLine = 512;

bool Simulated(std::uint16_t id) {
    switch (id) {
        case nv::msg_id::kInsPvaS:
        case nv::msg_id::kInsPvaX:
        case nv::msg_id::kBestPos:
        case nv::msg_id::kInsStdDev:
        case nv::msg_id::kTime:
        case nv::msg_id::kRawImuSX:
        case nv::msg_id::kInsConfig:
            return true;
        default:
            return false;
    }
}

std::string Errno(const char* what) {
    return std::string(what) + ": " + std::strerror(errno);
}

void SetNonBlocking(int fd) {
    ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) | O_NONBLOCK);
}

}  // namespace

std::vector<std::string> NovatelPortConfig::Validate() const {
    std::vector<std::string> p;
    if (id.empty()) p.push_back("novatel port: id must not be empty");
    if (port_name.empty()) p.push_back("novatel port: port_name must not be empty");
    if (!tcp && pty_link.empty()) p.push_back("novatel port: a pty needs a symlink path");
    if (!tcp && (baud < 1200 || baud > 4'000'000)) p.push_back("novatel port: baud 1200..4000000");
    if (tcp && (tcp_port < 1 || tcp_port > 65535)) p.push_back("novatel port: tcp_port 1..65535");
    if (!(unplug_s > 0)) p.push_back("novatel port: unplug_s must be > 0");
    return p;
}

NovatelPortEmulator::NovatelPortEmulator(NovatelPortConfig config,
                                         const ScenarioConfig& scenario,
                                         const TruthTrajectory& truth,
                                         const NavErrorModel& errors,
                                         std::int64_t start_utime_gps,
                                         const RealTimeBase& time,
                                         Manifest& manifest)
    : config_(std::move(config)),
      scenario_(scenario),
      time_(time),
      manifest_(manifest),
      receiver_(scenario, truth, errors, start_utime_gps),
      rng_state_(config_.seed * 0x9E3779B97F4A7C15ull + 1) {}

NovatelPortEmulator::~NovatelPortEmulator() {
    Stop();
    ClosePty();
    if (client_fd_ >= 0) ::close(client_fd_);
    if (listen_fd_ >= 0) ::close(listen_fd_);
}

Status NovatelPortEmulator::Open() {
    if (auto p = config_.Validate(); !p.empty()) return Error{p.front()};
    for (const auto& line : config_.default_logs) {
        std::string error;
        if (!ApplyLog(line, 0, error)) return Error{"default log '" + line + "': " + error};
    }
    if (!config_.tcp) return CreatePty();
    listen_fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
    if (listen_fd_ < 0) return Error{Errno("socket")};
    const int one = 1;
    ::setsockopt(listen_fd_, SOL_SOCKET, SO_REUSEADDR, &one, sizeof(one));
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_port = htons(static_cast<std::uint16_t>(config_.tcp_port));
    if (::inet_pton(AF_INET, config_.tcp_address.c_str(), &addr.sin_addr) != 1) {
        return Error{"ICOM emulator: '" + config_.tcp_address + "' is not an IPv4 address"};
    }
    if (::bind(listen_fd_, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) != 0) {
        const std::string why = std::strerror(errno);
        ::close(listen_fd_);
        listen_fd_ = -1;
        return Error{"ICOM emulator: cannot listen on " + config_.tcp_address + ":" +
                     std::to_string(config_.tcp_port) + " (" + why +
                     "; is the port busy? choose another with --tcp-port)"};
    }
    if (::listen(listen_fd_, 1) != 0) return Error{Errno("listen")};
    return Ok{};
}

Status NovatelPortEmulator::CreatePty() {
    int master = -1, slave = -1;
    if (::openpty(&master, &slave, nullptr, nullptr, nullptr) != 0) {
        return Error{"NovAtel emulator: no pseudo-terminal available (" +
                     std::string(std::strerror(errno)) + "; is /dev/pts mounted?)"};
    }
    // Raw from the start: a cooked slave would echo our own output back as commands.
    termios tio{};
    ::tcgetattr(slave, &tio);
    ::cfmakeraw(&tio);
    tio.c_cflag |= CLOCAL | CREAD;
    ::tcsetattr(slave, TCSANOW, &tio);
    ::fcntl(master, F_SETFD, FD_CLOEXEC);
    ::fcntl(slave, F_SETFD, FD_CLOEXEC);
    SetNonBlocking(master);
    char name[128] = {};
    if (::ptsname_r(master, name, sizeof(name)) != 0) {
        ::close(master);
        ::close(slave);
        return Error{Errno("ptsname")};
    }
    struct stat st {};
    if (::lstat(config_.pty_link.c_str(), &st) == 0 && !S_ISLNK(st.st_mode)) {
        ::close(master);
        ::close(slave);
        return Error{config_.pty_link + " exists and is not a symlink; choose another --pty"};
    }
    // Atomic replacement: a reader never sees the path missing or half made.
    const std::string tmp = config_.pty_link + ".new";
    ::unlink(tmp.c_str());
    if (::symlink(name, tmp.c_str()) != 0 || ::rename(tmp.c_str(), config_.pty_link.c_str()) != 0) {
        const std::string why = Errno(config_.pty_link.c_str());
        ::close(master);
        ::close(slave);
        return Error{"NovAtel emulator: cannot make the pty symlink " + why};
    }
    master_fd_ = master;
    slave_fd_ = slave;
    return Ok{};
}

void NovatelPortEmulator::ClosePty() {
    if (master_fd_ >= 0) ::close(master_fd_);
    if (slave_fd_ >= 0) ::close(slave_fd_);
    master_fd_ = slave_fd_ = -1;
}

void NovatelPortEmulator::Start(double end_s) {
    if (thread_.joinable()) return;
    stop_ = false;
    thread_ = std::thread([this, end_s] { Run(end_s); });
}

void NovatelPortEmulator::Stop() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
}

bool NovatelPortEmulator::Connected() const {
    return config_.tcp ? client_fd_ >= 0 : master_fd_ >= 0;
}

void NovatelPortEmulator::Run(double end_s) {
    while (!stop_.load()) {
        const double now = time_.NowS();
        if (now >= end_s && (line_.empty() || now >= end_s + kDrainLimitS)) break;
        if (now < end_s) {
            Generate(now);
            HandleFaults(now);
            MoveDueFrames(now);
        }
        ServiceLine(time_.NowS());
        // Sleep until the next byte slice, frame or command (at most 10 ms).
        double wait_s = 0.010;
        if (!line_.empty()) wait_s = 0.0005;
        if (!pending_.empty()) wait_s = std::min(wait_s, pending_.front().t_emit_s - now);
        wait_s = std::clamp(wait_s, 0.0002, 0.010);
        pollfd fds[2];
        nfds_t n = 0;
        if (config_.tcp) {
            if (client_fd_ >= 0) {
                fds[n++] = {client_fd_, POLLIN, 0};
            } else if (listen_fd_ >= 0 && !dropping_) {
                fds[n++] = {listen_fd_, POLLIN, 0};
            }
        } else if (master_fd_ >= 0) {
            fds[n++] = {master_fd_, POLLIN, 0};
        }
        const timespec ts{0, static_cast<long>(wait_s * 1e9)};
        if (::ppoll(fds, n, &ts, nullptr) > 0) ReadCommands(time_.NowS());
    }
    // The connection stays open until the emulator is destroyed, after the daemon stopped:
    // closing it here would show the daemon a drop nobody injected.
}

void NovatelPortEmulator::Generate(double now) {
    if (now < -kGenerateAheadS) return;
    while (generated_s_ < now + kGenerateAheadS) {
        const double t1 = generated_s_ + kGenerateBlockS;
        for (EmittedFrame& f : receiver_.Emit(generated_s_, t1)) pending_.push_back(std::move(f));
        generated_s_ = t1;
    }
}

void NovatelPortEmulator::HandleFaults(double now) {
    const auto due = [now](const std::vector<double>& times, std::size_t& next) {
        if (next < times.size() && times[next] <= now) {
            ++next;
            return true;
        }
        return false;
    };
    if (due(config_.garbage_times_s, next_garbage_) && Connected() && !unplugging_) {
        Item g;
        g.kind = "garbage";
        const int len = 16 + static_cast<int>((rng_state_ >> 33) % 113);
        for (int i = 0; i < len; ++i) {
            rng_state_ = rng_state_ * 6364136223846793005ull + 1442695040888963407ull;
            // Bytes that start no frame: no 0xAA sync, no '#', '%', '<', '[', '$', CR, LF.
            std::uint8_t b = static_cast<std::uint8_t>(rng_state_ >> 56);
            if (b == 0xAA || b == '#' || b == '%' || b == '<' || b == '[' || b == '$' ||
                b == '\r' || b == '\n') {
                b = 0x55;
            }
            g.bytes.push_back(b);
        }
        ++stats_.garbage_bursts;
        stats_.garbage_bytes += len;
        manifest_.Write(ManifestRecord("fault", config_.id)
                            .Str("fault", "garbage")
                            .Int("utime", time_.UnixAt(now))
                            .Num("t_s", now)
                            .Int("len", len));
        Push(std::move(g), now);
    }
    if (due(config_.crc_times_s, next_crc_)) ++corrupt_pending_;
    if (due(config_.unplug_times_s, next_unplug_) && !config_.tcp && master_fd_ >= 0) {
        unplugging_ = true;
        unplug_started_s_ = now;
        lost_in_fault_ = 0;
    }
    if (unplugging_ && line_.empty()) {
        int unread = 0;
        if (slave_fd_ >= 0) ::ioctl(slave_fd_, FIONREAD, &unread);
        if (unread == 0 || now - unplug_started_s_ > kUnplugDrainS) {
            ClosePty();
            ::unlink(config_.pty_link.c_str());
            unplugging_ = false;
            away_until_s_ = now + config_.unplug_s;
            ++stats_.unplugs;
            manifest_.Write(ManifestRecord("fault", config_.id)
                                .Str("fault", "unplug")
                                .Int("utime", time_.UnixAt(now))
                                .Num("t_s", now)
                                .Int("unread_bytes", unread));
        }
    }
    if (away_until_s_ >= 0 && now >= away_until_s_) {
        away_until_s_ = -1;
        const Status s = CreatePty();
        manifest_.Write(ManifestRecord("fault", config_.id)
                            .Str("fault", "replug")
                            .Int("utime", time_.UnixAt(now))
                            .Num("t_s", now)
                            .Int("lost_frames", lost_in_fault_)
                            .Str("error", s ? "" : s.error().message));
        lost_in_fault_ = 0;
    }
    if (due(config_.drop_times_s, next_drop_) && config_.tcp && client_fd_ >= 0) {
        ++stats_.tcp_drops;
        manifest_.Write(ManifestRecord("fault", config_.id)
                            .Str("fault", "tcp_drop")
                            .Int("utime", time_.UnixAt(now))
                            .Num("t_s", now));
        CloseClient("tcp_drop");
    }
}

void NovatelPortEmulator::MoveDueFrames(double now) {
    while (!pending_.empty() && pending_.front().t_emit_s <= now) {
        EmittedFrame f = std::move(pending_.front());
        pending_.pop_front();
        latest_[f.message_id] = f.bytes;
        auto it = logs_.find(f.message_id);
        if (it == logs_.end()) continue;
        ActiveLog& log = it->second;
        if (!log.every_update && f.t_emit_s - log.last_s < log.period_s - 1e-4) continue;
        log.last_s = f.t_emit_s;
        if (!Connected() || unplugging_) {
            ++stats_.lost_frames;
            ++lost_in_fault_;
            continue;
        }
        Item item;
        item.kind = "frame";
        item.message_id = f.message_id;
        item.bytes = std::move(f.bytes);
        item.start_s = f.t_emit_s;
        if (corrupt_pending_ > 0 && item.bytes.size() > 16) {
            // The last body byte, ahead of the CRC: the frame still frames, its CRC fails.
            item.bytes[item.bytes.size() - 5] ^= 0x01;
            item.kind = "corrupt_frame";
            --corrupt_pending_;
            ++stats_.crc_errors;
            manifest_.Write(ManifestRecord("fault", config_.id)
                                .Str("fault", "crc")
                                .Int("utime", time_.UnixAt(now))
                                .Num("t_s", now)
                                .Int("id", f.message_id));
        }
        const double ready_s = item.start_s;
        Push(std::move(item), ready_s);
    }
}

void NovatelPortEmulator::Push(Item item, double ready_s) {
    const double byte_s = config_.tcp ? 0.0 : 10.0 / config_.baud;  // 8N1
    item.start_s = std::max(ready_s, line_free_s_);
    line_free_s_ = item.start_s + static_cast<double>(item.bytes.size()) * byte_s;
    line_.push_back(std::move(item));
}

void NovatelPortEmulator::ServiceLine(double now) {
    const double byte_s = config_.tcp ? 0.0 : 10.0 / config_.baud;
    while (!line_.empty()) {
        const int fd = config_.tcp ? client_fd_ : master_fd_;
        Item& it = line_.front();
        if (fd < 0) {  // the port went away with items queued: they never reach the wire
            ++lost_in_fault_;
            line_.pop_front();
            continue;
        }
        std::size_t allowed = it.bytes.size();
        if (byte_s > 0) {
            if (now < it.start_s) return;
            allowed = std::min(it.bytes.size(),
                               static_cast<std::size_t>((now - it.start_s) / byte_s) + 1);
        }
        if (allowed > it.written) {
            const ssize_t n =
                config_.tcp
                    ? ::send(fd, it.bytes.data() + it.written, allowed - it.written, MSG_NOSIGNAL)
                    : ::write(fd, it.bytes.data() + it.written, allowed - it.written);
            if (n < 0) {
                if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) return;
                manifest_.Write(ManifestRecord("fault", config_.id)
                                    .Str("fault", "write_error")
                                    .Str("error", std::strerror(errno))
                                    .Int("written", static_cast<std::int64_t>(it.written))
                                    .Num("t_s", now));
                if (config_.tcp) CloseClient("write_error");
                return;
            }
            it.written += static_cast<std::size_t>(n);
            stats_.bytes += n;
        }
        if (it.written < it.bytes.size()) return;
        Record(it, now);
        line_.pop_front();
    }
}

void NovatelPortEmulator::Record(const Item& it, double now) {
    ManifestRecord r(it.kind, config_.id);
    r.Int("utime", time_.UnixAt(now)).Num("t_s", now).Bytes(it.bytes);
    if (it.message_id >= 0) r.Int("id", it.message_id);
    if (!it.command.empty()) r.Str("command", it.command);
    manifest_.Write(r);
    if (it.kind == "frame" || it.kind == "corrupt_frame") {
        ++stats_.frames;
        const double expected_end =
            it.start_s + static_cast<double>(it.bytes.size()) * 10.0 / config_.baud;
        const auto late = static_cast<std::int64_t>((now - expected_end) * 1e6);
        if (!config_.tcp) stats_.late_us_max = std::max(stats_.late_us_max, late);
    }
}

void NovatelPortEmulator::ReadCommands(double now) {
    if (config_.tcp && client_fd_ < 0) {
        const int fd = ::accept4(listen_fd_, nullptr, nullptr, SOCK_CLOEXEC | SOCK_NONBLOCK);
        if (fd < 0) return;
        const int one = 1;
        ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof(one));
        client_fd_ = fd;
        ++stats_.connections;
        line_free_s_ = now;
        manifest_.Write(
            ManifestRecord("connect", config_.id).Int("utime", time_.UnixAt(now)).Num("t_s", now));
        return;
    }
    const int fd = config_.tcp ? client_fd_ : master_fd_;
    if (fd < 0) return;
    char buf[1024];
    for (int rounds = 0; rounds < 16; ++rounds) {
        const ssize_t n = ::read(fd, buf, sizeof(buf));
        if (n == 0 && config_.tcp) {
            CloseClient("peer_closed");
            return;
        }
        if (n <= 0) return;  // EAGAIN; EIO on a pty whose reader closed is harmless
        for (ssize_t i = 0; i < n; ++i) {
            const char c = buf[i];
            if (c == '\r' || c == '\n') {
                if (!command_buffer_.empty()) HandleCommand(command_buffer_, now);
                command_buffer_.clear();
            } else if (command_buffer_.size() < kMaxCommandLine) {
                command_buffer_ += c;
            }
        }
    }
}

void NovatelPortEmulator::HandleCommand(const std::string& line, double now) {
    ++stats_.commands;
    const std::string error = ApplyCommand(line, now);
    Item item;
    item.kind = "response";
    item.command = line;
    nv::Response resp;
    resp.form = nv::Response::Form::kAbbreviated;
    resp.text = error.empty() ? "OK" : "ERROR:" + error;
    (error.empty() ? stats_.commands_ok : stats_.commands_refused)++;
    nv::EncodeAscii(nv::Message{resp}, item.bytes);
    nv::EncodeAscii(nv::Message{nv::PortPrompt{config_.port_name}}, item.bytes);
    manifest_.Write(ManifestRecord("command", config_.id)
                        .Int("utime", time_.UnixAt(now))
                        .Num("t_s", now)
                        .Str("command", line)
                        .Str("answer", resp.text));
    Push(std::move(item), now);
}

std::string NovatelPortEmulator::ApplyCommand(const std::string& line, double now) {
    auto parsed = nv::ParseCommand(line);
    if (std::holds_alternative<nv::CommandError>(parsed)) {
        const auto& e = std::get<nv::CommandError>(parsed);
        return e.kind == nv::CommandErrorKind::kUnknownCommand ? "Invalid Command Name"
                                                               : "Invalid Command";
    }
    const nv::Command& cmd = std::get<nv::Command>(parsed);
    if (std::holds_alternative<nv::LogCommand>(cmd)) {
        std::string error;
        ApplyLog(line, now, error);
        return error;
    }
    if (const auto* u = std::get_if<nv::UnlogCommand>(&cmd)) {
        const auto id = nv::MessageIdFromName(u->message);
        if (!id || logs_.erase(*id) == 0) return "Message Not Logged";
        return "";
    }
    if (std::holds_alternative<nv::UnlogAllCommand>(cmd)) {
        logs_.clear();
        return "";
    }
    return "";  // INTERFACEMODE, SERIALCONFIG: accepted, nothing to simulate
}

bool NovatelPortEmulator::ApplyLog(const std::string& text, double now, std::string& error) {
    auto parsed = nv::ParseCommand(text);
    const nv::LogCommand* log = nullptr;
    if (auto* cmd = std::get_if<nv::Command>(&parsed)) log = std::get_if<nv::LogCommand>(cmd);
    if (log == nullptr) {
        error = "Invalid Command";
        return false;
    }
    if (!log->port.empty() && log->port != "THISPORT" && log->port != config_.port_name) {
        error = "Invalid Port (the emulator serves " + config_.port_name + " only)";
        return false;
    }
    const auto id = nv::MessageIdFromName(log->message);
    if (!id) {
        error = "Invalid Message ID";
        return false;
    }
    if (!Simulated(*id)) {
        error = "Message ID not simulated";
        return false;
    }
    if (log->format != nv::LogFormat::kBinary) {
        error = "Only binary logs are simulated";
        return false;
    }
    const bool immediate =
        log->trigger == nv::LogTrigger::kOnChanged || log->trigger == nv::LogTrigger::kOnce;
    if (immediate) {
        auto it = latest_.find(*id);
        if (it != latest_.end() && Connected()) {
            Item item;
            item.kind = "frame";
            item.message_id = *id;
            item.bytes = it->second;
            Push(std::move(item), now);
        }
    }
    if (log->trigger == nv::LogTrigger::kOnce) return true;
    ActiveLog a;
    a.every_update = log->trigger != nv::LogTrigger::kOnTime || !log->period_s;
    a.period_s = log->period_s.value_or(0.0);
    logs_[*id] = a;
    return true;
}

void NovatelPortEmulator::CloseClient(const char* why) {
    if (client_fd_ < 0) return;
    // Half-close, then read what the peer still sends until it closes too: closing with
    // unread input would reset the connection and destroy bytes still in flight to it.
    ::shutdown(client_fd_, SHUT_WR);
    const double until = time_.NowS() + 0.5;
    char buf[512];
    while (time_.NowS() < until) {
        pollfd p{client_fd_, POLLIN, 0};
        if (::poll(&p, 1, 20) <= 0) continue;
        if (::read(client_fd_, buf, sizeof(buf)) <= 0) break;
    }
    ::close(client_fd_);
    client_fd_ = -1;
    logs_.clear();  // ICOM logs end with the connection
    command_buffer_.clear();
    line_.clear();
    manifest_.Write(ManifestRecord("disconnect", config_.id)
                        .Int("utime", time_.UnixAt(time_.NowS()))
                        .Num("t_s", time_.NowS())
                        .Str("why", why));
}

}  // namespace pitmap::sim::hil
