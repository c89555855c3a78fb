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
// (0 when absent), the sender (when `from` is not null) and the MSG_TRUNC flag.
long RecvWithTimestamp(int fd,
                       std::byte* dst,
                       std::size_t capacity,
                       std::int64_t& utime_kernel,
                       sockaddr_in* from,
                       bool* truncated);

}  // namespace pitmap::acq::detail
