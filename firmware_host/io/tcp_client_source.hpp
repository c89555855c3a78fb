// SPDX-License-Identifier: MIT
// TcpClientSource: a TCP client (NovAtel ICOM ports 3001..3007, the Delta T head on 4040).
//
// Connects with a timeout (non-blocking connect + poll), enables SO_KEEPALIVE with
// TCP_KEEPIDLE/INTVL/CNT so a dead peer is noticed within idle + intvl*cnt seconds even
// when the line is silent, TCP_NODELAY for commands, and SO_TIMESTAMPNS so a chunk carries
// the kernel receive time of its last segment where the kernel provides one (often not on
// TCP: then utime_kernel is 0). A peer that closes or resets the connection
// makes the source kDisconnected; Read() reconnects with bounded backoff. TCP segments do
// not respect message boundaries: the framer downstream reassembles.
//
// THREADING: as ByteSource (one owner thread).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "firmware_host/io/detail/stream_source.hpp"

namespace pitmap::acq {

struct TcpClientConfig {
    std::string host;                       // numeric IPv4 address or a name /etc/hosts resolves
    int port = 3001;                        // TCP port, 1..65535
    int connect_timeout_ms = 2000;          // one connect attempt, milliseconds
    int keepalive_idle_s = 5;               // idle time before the first probe, seconds
    int keepalive_interval_s = 1;           // between probes, seconds
    int keepalive_count = 3;                // unanswered probes before the connection is dropped
    std::size_t read_buffer_bytes = 65536;  // largest chunk one Read() returns, bytes
    BackoffConfig reconnect_backoff{};      // reconnect delays after a loss

    std::vector<std::string> Validate() const;
};

class TcpClientSource final : public detail::StreamSource {
public:
    // Precondition: config.Validate() is empty.
    explicit TcpClientSource(TcpClientConfig config);

    Transport transport() const override { return Transport::kTcp; }
    std::string description() const override;

protected:
    Expected<detail::UniqueFd> OpenFd() override;
    long ReadSome(int fd,
                  std::byte* dst,
                  std::size_t capacity,
                  std::int64_t& utime_kernel) override;
    long WriteSome(int fd, const std::byte* src, std::size_t size) override;
    std::string peer() const override { return peer_; }

private:
    TcpClientConfig config_;
    std::string peer_;
};

}  // namespace pitmap::acq
