// SPDX-License-Identifier: MIT
#include "firmware_host/io/udp_source.hpp"

#include <arpa/inet.h>
#include <poll.h>
#include <sys/socket.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <utility>

#include "firmware_host/io/detail/socket_util.hpp"

namespace pitmap::acq {

std::vector<std::string> UdpConfig::Validate() const {
    std::vector<std::string> problems;
    in_addr a{};
    if (::inet_pton(AF_INET, bind_address.c_str(), &a) != 1) {
        problems.push_back("udp: bind_address '" + bind_address +
                           "' is not a numeric IPv4 address");
    }
    if (port < 0 || port > 65535) problems.push_back("udp: port must be 0..65535");
    if (receive_buffer_bytes <= 0) problems.push_back("udp: receive_buffer_bytes must be > 0");
    if (max_datagram_bytes == 0) problems.push_back("udp: max_datagram_bytes must be > 0");
    if (rebind_backoff.initial_ms <= 0 || rebind_backoff.max_ms < rebind_backoff.initial_ms ||
        rebind_backoff.factor < 1.0) {
        problems.push_back("udp: rebind_backoff needs 0 < initial_ms <= max_ms, factor >= 1");
    }
    return problems;
}

std::string UdpEndpoint::ToString() const {
    sockaddr_in s{};
    s.sin_family = AF_INET;
    s.sin_addr.s_addr = htonl(address);
    s.sin_port = htons(port);
    return detail::FormatEndpoint(s);
}

std::optional<UdpEndpoint> UdpEndpoint::Parse(const std::string& text) {
    const auto colon = text.rfind(':');
    if (colon == std::string::npos) return std::nullopt;
    in_addr a{};
    if (::inet_pton(AF_INET, text.substr(0, colon).c_str(), &a) != 1) return std::nullopt;
    const std::string p = text.substr(colon + 1);
    if (p.empty() || p.size() > 5 ||
        !std::all_of(p.begin(), p.end(), [](char c) { return c >= '0' && c <= '9'; })) {
        return std::nullopt;
    }
    const int port = std::stoi(p);
    if (port > 65535) return std::nullopt;
    return UdpEndpoint{ntohl(a.s_addr), static_cast<std::uint16_t>(port)};
}

UdpSource::UdpSource(UdpConfig config)
    : config_(std::move(config)), backoff_(config_.rebind_backoff) {
    PITMAP_CHECK(config_.Validate().empty(), "UdpSource: invalid config");
}

std::string UdpSource::description() const {
    return "udp " + config_.bind_address + ":" + std::to_string(config_.port);
}

Status UdpSource::TryOpen() {
    set_state(SourceState::kConnecting);
    auto fail = [&](const std::string& what) -> Status {
        const int err = errno;
        fd_.Reset();
        backoff_.Failed(MonotonicNowUs());
        set_state(SourceState::kDisconnected);
        return Fail(detail::ErrnoMessage(what, err));
    };
    fd_.Reset(::socket(AF_INET, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0));
    if (!fd_.valid()) return fail("udp: socket");
    const int size = config_.receive_buffer_bytes;
    // SO_RCVBUFFORCE ignores rmem_max but needs CAP_NET_ADMIN; fall back to the capped option.
    if (::setsockopt(fd_.get(), SOL_SOCKET, SO_RCVBUFFORCE, &size, sizeof(size)) != 0) {
        ::setsockopt(fd_.get(), SOL_SOCKET, SO_RCVBUF, &size, sizeof(size));
    }
    socklen_t len = sizeof(granted_rcvbuf_);
    ::getsockopt(fd_.get(), SOL_SOCKET, SO_RCVBUF, &granted_rcvbuf_, &len);
    if (config_.kernel_timestamps) {
        const int one = 1;
        ::setsockopt(fd_.get(), SOL_SOCKET, SO_TIMESTAMPNS, &one, sizeof(one));
    }
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_port = htons(static_cast<std::uint16_t>(config_.port));
    ::inet_pton(AF_INET, config_.bind_address.c_str(), &addr.sin_addr);
    if (::bind(fd_.get(), reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)) != 0) {
        return fail("udp: bind " + config_.bind_address + ":" + std::to_string(config_.port));
    }
    sockaddr_in bound{};
    len = sizeof(bound);
    ::getsockname(fd_.get(), reinterpret_cast<sockaddr*>(&bound), &len);
    bound_port_ = ntohs(bound.sin_port);
    backoff_.Succeeded();
    NoteOpened();
    return Ok{};
}

Status UdpSource::Open() {
    if (fd_.valid()) return Ok{};
    return TryOpen();
}

void UdpSource::Close() {
    fd_.Reset();
    backoff_.Succeeded();
    bound_port_ = 0;
    granted_rcvbuf_ = 0;
    set_state(SourceState::kClosed);
}

Expected<ReadOutcome> UdpSource::Read(Chunk& chunk, int timeout_ms) {
    const std::int64_t deadline = MonotonicNowUs() + std::max(timeout_ms, 0) * 1000LL;
    if (!fd_.valid()) {
        const std::int64_t now = MonotonicNowUs();
        if (!backoff_.Ready(now)) {
            const std::int64_t wake = std::min(deadline, backoff_.next_attempt_us());
            detail::SleepMs(static_cast<int>((wake - now + 999) / 1000));
            if (!backoff_.Ready(MonotonicNowUs())) return ReadOutcome::kTimeout;
        }
        auto opened = TryOpen();
        if (!opened) return opened.error();
    }
    const std::int64_t left_us = deadline - MonotonicNowUs();
    const int left_ms = left_us <= 0 ? 0 : static_cast<int>((left_us + 999) / 1000);
    const auto p = detail::PollFd(fd_.get(), POLLIN, left_ms);
    if (p == detail::PollResult::kTimeout) return ReadOutcome::kTimeout;
    if (p != detail::PollResult::kReady) {
        // A datagram socket reports POLLERR for a queued ICMP error (after SendTo to a closed
        // port); reading the error queue clears it. Not a loss of the socket.
        int err = 0;
        socklen_t len = sizeof(err);
        ::getsockopt(fd_.get(), SOL_SOCKET, SO_ERROR, &err, &len);
        return Fail(detail::ErrnoMessage(description() + ": socket error", err));
    }
    chunk.data.resize(config_.max_datagram_bytes);
    sockaddr_in from{};
    bool truncated = false;
    long n;
    do {
        n = detail::RecvWithTimestamp(fd_.get(), chunk.data.data(), chunk.data.size(),
                                      chunk.utime_kernel, &from, &truncated);
    } while (n < 0 && errno == EINTR);
    chunk.utime_host = HostNowUtime();
    if (n < 0) {
        if (errno == EAGAIN || errno == EWOULDBLOCK) return ReadOutcome::kTimeout;
        // ECONNREFUSED etc. are ICMP reports about an earlier SendTo; the socket stays usable.
        return Fail(detail::ErrnoMessage(description() + ": recvmsg", errno));
    }
    // With MSG_TRUNC set in msg_flags, n is the part that fitted (recvmsg returns the copied
    // length unless MSG_TRUNC is passed in flags).
    chunk.data.resize(std::min(static_cast<std::size_t>(n), chunk.data.size()));
    chunk.truncated = truncated;
    if (truncated) ++truncated_;
    last_sender_ = UdpEndpoint{ntohl(from.sin_addr.s_addr), ntohs(from.sin_port)};
    chunk.peer = detail::FormatEndpoint(from);
    return ReadOutcome::kData;
}

Status UdpSource::SendTo(std::span<const std::byte> bytes, const UdpEndpoint& to) {
    if (!fd_.valid()) return Fail(description() + ": send while not open");
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_addr.s_addr = htonl(to.address);
    addr.sin_port = htons(to.port);
    long n;
    do {
        n = ::sendto(fd_.get(), bytes.data(), bytes.size(), MSG_DONTWAIT,
                     reinterpret_cast<const sockaddr*>(&addr), sizeof(addr));
    } while (n < 0 && errno == EINTR);
    if (n < 0)
        return Fail(detail::ErrnoMessage(description() + ": sendto " + to.ToString(), errno));
    if (static_cast<std::size_t>(n) != bytes.size()) {
        return Fail(description() + ": sendto " + to.ToString() + " sent a partial datagram");
    }
    return Ok{};
}

Status UdpSource::Write(std::span<const std::byte> bytes, int) {
    if (!last_sender_) return Fail(description() + ": no sender to reply to yet");
    return SendTo(bytes, *last_sender_);
}

}  // namespace pitmap::acq
