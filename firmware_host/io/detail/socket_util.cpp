// SPDX-License-Identifier: MIT
#include "firmware_host/io/detail/socket_util.hpp"

#include <arpa/inet.h>
#include <sys/uio.h>

#include <cstring>
#include <ctime>

#include "firmware_host/io/detail/fd_util.hpp"

namespace pitmap::acq::detail {

std::string FormatEndpoint(const sockaddr_in& addr) {
    char buf[INET_ADDRSTRLEN] = {};
    ::inet_ntop(AF_INET, &addr.sin_addr, buf, sizeof(buf));
    return std::string(buf) + ":" + std::to_string(ntohs(addr.sin_port));
}

long RecvWithTimestamp(int fd,
                       std::byte* dst,
                       std::size_t capacity,
                       std::int64_t& utime_kernel,
                       sockaddr_in* from,
                       bool* truncated,
                       std::uint32_t* rxq_ovfl) {
    iovec iov{dst, capacity};
    alignas(cmsghdr) char
        control[CMSG_SPACE(sizeof(timespec)) * 2 + CMSG_SPACE(sizeof(std::uint32_t))] = {};
    msghdr msg{};
    msg.msg_iov = &iov;
    msg.msg_iovlen = 1;
    msg.msg_control = control;
    msg.msg_controllen = sizeof(control);
    if (from != nullptr) {
        msg.msg_name = from;
        msg.msg_namelen = sizeof(*from);
    }
    const long n = ::recvmsg(fd, &msg, MSG_DONTWAIT);
    utime_kernel = 0;
    if (n < 0) return n;
    if (truncated != nullptr) *truncated = (msg.msg_flags & MSG_TRUNC) != 0;
    for (cmsghdr* c = CMSG_FIRSTHDR(&msg); c != nullptr; c = CMSG_NXTHDR(&msg, c)) {
        if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SCM_TIMESTAMPNS &&
            c->cmsg_len >= CMSG_LEN(sizeof(timespec))) {
            timespec ts{};
            std::memcpy(&ts, CMSG_DATA(c), sizeof(ts));
            utime_kernel = UtimeFromTimespec(ts.tv_sec, ts.tv_nsec);
        } else if (rxq_ovfl != nullptr && c->cmsg_level == SOL_SOCKET &&
                   c->cmsg_type == SO_RXQ_OVFL && c->cmsg_len >= CMSG_LEN(sizeof(std::uint32_t))) {
            std::memcpy(rxq_ovfl, CMSG_DATA(c), sizeof(std::uint32_t));
        }
    }
    return n;
}

}  // namespace pitmap::acq::detail
