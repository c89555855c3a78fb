// SPDX-License-Identifier: MIT
// UdpSource: receives datagrams on a bound port (Delta T 83P records, default UDP 4040).
//
// One datagram per chunk, with the kernel receive time (SO_TIMESTAMPNS via recvmsg) and the
// sender address, which the daemon needs to answer with External Control frames (SendTo /
// Write, Imagenex spec §3.2). The receive buffer is asked for large (8 MiB by default;
// SO_RCVBUFFORCE when privileged, else SO_RCVBUF, capped by net.core.rmem_max) and the size
// the kernel granted is reported. A datagram longer than the buffer is delivered cut and
// flagged (Chunk::truncated, MSG_TRUNC). IPv4 only.
//
// THREADING: as ByteSource (one owner thread).
#pragma once

#include <netinet/in.h>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "firmware_host/io/backoff.hpp"
#include "firmware_host/io/byte_source.hpp"
#include "firmware_host/io/detail/fd_util.hpp"

namespace pitmap::acq {

struct UdpConfig {
    std::string bind_address = "0.0.0.0";    // numeric IPv4 address to bind
    int port = 4040;                         // UDP port, 0..65535 (0 = any, for tests)
    int receive_buffer_bytes = 8 << 20;      // requested SO_RCVBUF, bytes
    std::size_t max_datagram_bytes = 65536;  // receive buffer per datagram, bytes
    bool kernel_timestamps = true;           // SO_TIMESTAMPNS
    BackoffConfig rebind_backoff{};          // retries when bind fails

    std::vector<std::string> Validate() const;
};

// An IPv4 address and port, host byte order.
struct UdpEndpoint {
    std::uint32_t address = 0;
    std::uint16_t port = 0;
    std::string ToString() const;
    // Parses "a.b.c.d:port".
    static std::optional<UdpEndpoint> Parse(const std::string& text);
};

class UdpSource final : public ByteSource {
public:
    // Precondition: config.Validate() is empty.
    explicit UdpSource(UdpConfig config);

    Status Open() override;
    Expected<ReadOutcome> Read(Chunk& chunk, int timeout_ms) override;
    // Sends `bytes` as one datagram to the sender of the last datagram received.
    Status Write(std::span<const std::byte> bytes, int timeout_ms) override;
    void Close() override;
    Transport transport() const override { return Transport::kUdp; }
    std::string description() const override;

    // Sends one datagram to `to`.
    Status SendTo(std::span<const std::byte> bytes, const UdpEndpoint& to);
    // The sender of the last datagram, if any.
    const std::optional<UdpEndpoint>& last_sender() const { return last_sender_; }
    // The bound port (useful with port 0), 0 when closed.
    int bound_port() const { return bound_port_; }
    // SO_RCVBUF as the kernel reports it after the request (Linux doubles the value it
    // books), bytes; 0 when closed.
    int granted_receive_buffer_bytes() const { return granted_rcvbuf_; }
    // Datagrams that were longer than max_datagram_bytes.
    std::int64_t truncated_datagrams() const { return truncated_; }

private:
    Status TryOpen();

    UdpConfig config_;
    detail::UniqueFd fd_;
    Backoff backoff_;
    std::optional<UdpEndpoint> last_sender_;
    int bound_port_ = 0;
    int granted_rcvbuf_ = 0;
    std::int64_t truncated_ = 0;
};

}  // namespace pitmap::acq
