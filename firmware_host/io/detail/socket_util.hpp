// SPDX-License-Identifier: MIT
// Private socket helpers of io/.
#pragma once

#include <netinet/in.h>
#include <sys/socket.h>

#include <cstddef>
#include <cstdint>
#include <string>

namespace pitmap::acq::detail {

// "a.b.c.d:port" of an IPv4 socket address.
std::string FormatEndpoint(const sockaddr_in& addr);

// recvmsg() of up to `capacity` bytes that also returns the SO_TIMESTAMPNS control message
// (0 when absent), the sender (when `from` is not null) and the MSG_TRUNC flag. With
// SO_RXQ_OVFL enabled on the socket and `rxq_ovfl` not null, *rxq_ovfl receives the socket's
// cumulative drop counter as the kernel stamped it on this datagram when it queued it (the
// kernel attaches it only once it is non-zero; *rxq_ovfl is left alone otherwise).
long RecvWithTimestamp(int fd,
                       std::byte* dst,
                       std::size_t capacity,
                       std::int64_t& utime_kernel,
                       sockaddr_in* from,
                       bool* truncated,
                       std::uint32_t* rxq_ovfl = nullptr);

}  // namespace pitmap::acq::detail
