// SPDX-License-Identifier: MIT
#include "firmware_host/io/udp_source.hpp"

#include <arpa/inet.h>
#include <linux/sock_diag.h>
#include <poll.h>
#include <sys/socket.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <utility>

#include "firmware_host/io/detail/socket_util.hpp"

namespace pitmap::acq {

namespace {

std::string AddressText(std::uint32_t address) {
    in_addr a{};
    a.s_addr = htonl(address);
    char buf[INET_ADDRSTRLEN] = {};
    ::inet_ntop(AF_INET, &a, buf, sizeof(buf));
    return buf;
}

// The local address the kernel would use to reach `remote` (a connected UDP socket sends
// nothing; connect() only picks the route and source address).
Expected<std::string> LocalAddressTowards(const UdpEndpoint& remote) {
    detail::UniqueFd fd(::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0));
    if (!fd.valid()) return Error{detail::ErrnoMessage("udp: socket", errno)};
    sockaddr_in to{};
    to.sin_family = AF_INET;
    to.sin_addr.s_addr = htonl(remote.address);
    to.sin_port = htons(remote.port != 0 ? remote.port : 9);
    if (::connect(fd.get(), reinterpret_cast<const sockaddr*>(&to), sizeof(to)) != 0) {
        return Error{detail::ErrnoMessage(
            "udp: no local address towards " + AddressText(remote.address), errno)};
    }
    sockaddr_in local{};
    socklen_t len = sizeof(local);
    if (::getsockname(fd.get(), reinterpret_cast<sockaddr*>(&local), &len) != 0) {
        return Error{detail::ErrnoMessage("udp: getsockname", errno)};
    }
    return AddressText(ntohl(local.sin_addr.s_addr));
}

}  // namespace

std::vector<std::string> UdpConfig::Validate() const {
    std::vector<std::string> problems;
    in_addr a{};
    if (!bind_address.empty() && ::inet_pton(AF_INET, bind_address.c_str(), &a) != 1) {
        problems.push_back("udp: bind_address '" + bind_address +
                           "' is not a numeric IPv4 address");
    }
    if (bind_address.empty() && allowed_senders.empty()) {
        problems.push_back("udp: bind_address is required when allowed_senders is empty");
    }
    if (port < 0 || port > 65535) problems.push_back("udp: port must be 0..65535");
    if (receive_buffer_bytes <= 0) problems.push_back("udp: receive_buffer_bytes must be > 0");
    if (max_datagram_bytes == 0) problems.push_back("udp: max_datagram_bytes must be > 0");
    if (rebind_backoff.initial_ms <= 0 || rebind_backoff.max_ms < rebind_backoff.initial_ms ||
        rebind_backoff.factor < 1.0) {
        problems.push_back("udp: rebind_backoff needs 0 < initial_ms <= max_ms, factor >= 1");
    }
    std::vector<std::uint32_t> allowed_addresses;
    for (const auto& text : allowed_senders) {
        const auto e = UdpEndpoint::ParseAddressOptionalPort(text);
        if (!e || e->address == 0) {
            problems.push_back("udp: allowed_senders entry '" + text +
                               "' is not \"a.b.c.d\" or \"a.b.c.d:port\" (0.0.0.0 not allowed)");
        } else {
            allowed_addresses.push_back(e->address);
        }
    }
    if (!reply_to.empty()) {
        const auto e = UdpEndpoint::ParseAddressOptionalPort(reply_to);
        if (!e || e->address == 0) {
            problems.push_back("udp: reply_to '" + reply_to +
                               "' is not \"a.b.c.d\" or \"a.b.c.d:port\"");
        } else if (e->port == 0 && !allowed_senders.empty() &&
                   std::find(allowed_addresses.begin(), allowed_addresses.end(), e->address) ==
                       allowed_addresses.end()) {
            problems.push_back("udp: reply_to '" + reply_to +
                               "' has no port and is not an allowed sender, so its port can "
                               "never be learned; add the port or list the address");
        }
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

std::optional<UdpEndpoint> UdpEndpoint::ParseAddressOptionalPort(const std::string& text) {
    if (text.find(':') != std::string::npos) {
        auto e = Parse(text);
        if (!e || e->port == 0) return std::nullopt;
        return e;
    }
    in_addr a{};
    if (::inet_pton(AF_INET, text.c_str(), &a) != 1) return std::nullopt;
    return UdpEndpoint{ntohl(a.s_addr), 0};
}

UdpSource::UdpSource(UdpConfig config)
    : config_(std::move(config)), backoff_(config_.rebind_backoff) {
    PITMAP_CHECK(config_.Validate().empty(), "UdpSource: invalid config");
    for (const auto& text : config_.allowed_senders) {
        allowed_.push_back(*UdpEndpoint::ParseAddressOptionalPort(text));
    }
    if (!config_.reply_to.empty()) {
        reply_ = UdpEndpoint::ParseAddressOptionalPort(config_.reply_to);
    } else if (!allowed_.empty()) {
        reply_ = allowed_.front();
    }
}

std::string UdpSource::description() const {
    const std::string& address = !bound_address_.empty()         ? bound_address_
                                 : !config_.bind_address.empty() ? config_.bind_address
                                                                 : std::string("(auto)");
    return "udp " + address + ":" + std::to_string(config_.port);
}

bool UdpSource::Allowed(const UdpEndpoint& from) const {
    if (allowed_.empty()) return true;
    return std::any_of(allowed_.begin(), allowed_.end(), [&](const UdpEndpoint& a) {
        return a.address == from.address && (a.port == 0 || a.port == from.port);
    });
}

std::optional<UdpEndpoint> UdpSource::reply_endpoint() const {
    if (!reply_) return last_sender_;
    if (reply_->port != 0) return reply_;
    if (reply_port_learned_ == 0) return std::nullopt;
    return UdpEndpoint{reply_->address, reply_port_learned_};
}

void UdpSource::NoteDropCounter(std::uint32_t cumulative) {
    // The counter wraps at 2^32; a datagram read now may carry an older value than a
    // SO_MEMINFO reading taken before it, so only forward steps count.
    const auto step = static_cast<std::int32_t>(cumulative - drops_seen_);
    if (step <= 0) return;
    AddKernelDrops(step);
    drops_seen_ = cumulative;
}

void UdpSource::PollDropCounter() {
    // SO_MEMINFO reports the current counter, so drops show even when no datagram follows
    // them (the SO_RXQ_OVFL control message only rides on a later datagram).
    std::uint32_t meminfo[SK_MEMINFO_VARS] = {};
    socklen_t len = sizeof(meminfo);
    if (::getsockopt(fd_.get(), SOL_SOCKET, SO_MEMINFO, meminfo, &len) == 0 &&
        len >= (SK_MEMINFO_DROPS + 1) * sizeof(std::uint32_t)) {
        NoteDropCounter(meminfo[SK_MEMINFO_DROPS]);
    }
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
    {
        const int one = 1;
        ::setsockopt(fd_.get(), SOL_SOCKET, SO_RXQ_OVFL, &one, sizeof(one));
        drops_seen_ = 0;  // a new socket counts from 0
    }
    std::string address = config_.bind_address;
    if (address.empty()) {
        // The interface facing the sonar, looked up again at every open (it may come up late).
        auto local = LocalAddressTowards(allowed_.front());
        if (!local) {
            fd_.Reset();
            backoff_.Failed(MonotonicNowUs());
            set_state(SourceState::kDisconnected);
            return Fail(local.error().message);
        }
        address = *local;
    }
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_port = htons(static_cast<std::uint16_t>(config_.port));
    ::inet_pton(AF_INET, address.c_str(), &addr.sin_addr);
    if (::bind(fd_.get(), reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)) != 0) {
        return fail("udp: bind " + address + ":" + std::to_string(config_.port));
    }
    sockaddr_in bound{};
    len = sizeof(bound);
    ::getsockname(fd_.get(), reinterpret_cast<sockaddr*>(&bound), &len);
    bound_port_ = ntohs(bound.sin_port);
    bound_address_ = address;
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
    bound_address_.clear();
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
    PollDropCounter();
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
    std::uint32_t rxq_ovfl = drops_seen_;
    long n;
    do {
        n = detail::RecvWithTimestamp(fd_.get(),
                                      chunk.data.data(),
                                      chunk.data.size(),
                                      chunk.utime_kernel,
                                      &from,
                                      &truncated,
                                      &rxq_ovfl);
    } while (n < 0 && errno == EINTR);
    NoteDropCounter(rxq_ovfl);
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
    const UdpEndpoint sender{ntohl(from.sin_addr.s_addr), ntohs(from.sin_port)};
    chunk.peer = detail::FormatEndpoint(from);
    chunk.foreign = !Allowed(sender);
    if (chunk.foreign) {
        ++foreign_;
    } else {
        last_sender_ = sender;
        if (reply_ && reply_->port == 0 && sender.address == reply_->address) {
            reply_port_learned_ = sender.port;
        }
    }
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
        n = ::sendto(fd_.get(),
                     bytes.data(),
                     bytes.size(),
                     MSG_DONTWAIT,
                     reinterpret_cast<const sockaddr*>(&addr),
                     sizeof(addr));
    } while (n < 0 && errno == EINTR);
    if (n < 0)
        return Fail(detail::ErrnoMessage(description() + ": sendto " + to.ToString(), errno));
    if (static_cast<std::size_t>(n) != bytes.size()) {
        return Fail(description() + ": sendto " + to.ToString() + " sent a partial datagram");
    }
    return Ok{};
}

Status UdpSource::Write(std::span<const std::byte> bytes, int) {
    const auto to = reply_endpoint();
    if (!to) {
        return Fail(description() + ": no datagram from " +
                    (reply_ ? AddressText(reply_->address) : std::string("any sender")) +
                    " yet, so no port to reply to");
    }
    return SendTo(bytes, *to);
}

}  // namespace pitmap::acq
