// SPDX-License-Identifier: MIT
#include "firmware_host/io/tcp_client_source.hpp"

#include <netdb.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <utility>

#include "firmware_host/io/detail/socket_util.hpp"

namespace pitmap::acq {

std::vector<std::string> TcpClientConfig::Validate() const {
    std::vector<std::string> problems;
    if (host.empty()) problems.push_back("tcp: host is empty");
    if (port < 1 || port > 65535) problems.push_back("tcp: port must be 1..65535");
    if (connect_timeout_ms <= 0) problems.push_back("tcp: connect_timeout_ms must be > 0");
    if (keepalive_idle_s <= 0 || keepalive_interval_s <= 0 || keepalive_count <= 0) {
        problems.push_back(
            "tcp: keepalive_idle_s, keepalive_interval_s, keepalive_count must be > 0");
    }
    if (read_buffer_bytes == 0) problems.push_back("tcp: read_buffer_bytes must be > 0");
    if (reconnect_backoff.initial_ms <= 0 ||
        reconnect_backoff.max_ms < reconnect_backoff.initial_ms || reconnect_backoff.factor < 1.0) {
        problems.push_back("tcp: reconnect_backoff needs 0 < initial_ms <= max_ms, factor >= 1");
    }
    return problems;
}

TcpClientSource::TcpClientSource(TcpClientConfig config)
    : StreamSource(config.reconnect_backoff, config.read_buffer_bytes), config_(std::move(config)) {
    PITMAP_CHECK(config_.Validate().empty(), "TcpClientSource: invalid config");
}

std::string TcpClientSource::description() const {
    return "tcp " + config_.host + ":" + std::to_string(config_.port);
}

Expected<detail::UniqueFd> TcpClientSource::OpenFd() {
    addrinfo hints{};
    hints.ai_family = AF_INET;
    hints.ai_socktype = SOCK_STREAM;
    hints.ai_flags = AI_NUMERICSERV;
    addrinfo* res = nullptr;
    const std::string port = std::to_string(config_.port);
    const int gai = ::getaddrinfo(config_.host.c_str(), port.c_str(), &hints, &res);
    if (gai != 0 || res == nullptr) {
        return Error{"tcp: cannot resolve " + config_.host + ": " + ::gai_strerror(gai)};
    }
    sockaddr_in addr{};
    std::memcpy(&addr, res->ai_addr, sizeof(addr));
    ::freeaddrinfo(res);

    detail::UniqueFd fd(::socket(AF_INET, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0));
    if (!fd.valid()) return Error{detail::ErrnoMessage("tcp: socket", errno)};
    const int one = 1;
    ::setsockopt(fd.get(), SOL_SOCKET, SO_KEEPALIVE, &one, sizeof(one));
    ::setsockopt(fd.get(), IPPROTO_TCP, TCP_KEEPIDLE, &config_.keepalive_idle_s, sizeof(int));
    ::setsockopt(fd.get(), IPPROTO_TCP, TCP_KEEPINTVL, &config_.keepalive_interval_s, sizeof(int));
    ::setsockopt(fd.get(), IPPROTO_TCP, TCP_KEEPCNT, &config_.keepalive_count, sizeof(int));
    ::setsockopt(fd.get(), IPPROTO_TCP, TCP_NODELAY, &one, sizeof(one));
    ::setsockopt(fd.get(), SOL_SOCKET, SO_TIMESTAMPNS, &one, sizeof(one));

    const std::string what = "tcp: connect " + detail::FormatEndpoint(addr);
    if (::connect(fd.get(), reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)) != 0) {
        if (errno != EINPROGRESS) return Error{detail::ErrnoMessage(what, errno)};
        const auto p = detail::PollFd(fd.get(), POLLOUT, config_.connect_timeout_ms);
        if (p == detail::PollResult::kTimeout) {
            return Error{what + ": timed out after " + std::to_string(config_.connect_timeout_ms) +
                         " ms"};
        }
        int err = 0;
        socklen_t len = sizeof(err);
        if (::getsockopt(fd.get(), SOL_SOCKET, SO_ERROR, &err, &len) != 0) err = errno;
        if (err != 0) return Error{detail::ErrnoMessage(what, err)};
    }
    peer_ = detail::FormatEndpoint(addr);
    return fd;
}

long TcpClientSource::ReadSome(int fd,
                               std::byte* dst,
                               std::size_t capacity,
                               std::int64_t& utime_kernel) {
    return detail::RecvWithTimestamp(fd, dst, capacity, utime_kernel, nullptr, nullptr);
}

long TcpClientSource::WriteSome(int fd, const std::byte* src, std::size_t size) {
    // MSG_NOSIGNAL: a peer that went away gives EPIPE, not a process-killing SIGPIPE.
    return ::send(fd, src, size, MSG_NOSIGNAL | MSG_DONTWAIT);
}

}  // namespace pitmap::acq
