// SPDX-License-Identifier: MIT
// UdpSource: receives datagrams on a bound port (Delta T 83P records, default UDP 4040).
//
// One datagram per chunk, with the kernel receive time (SO_TIMESTAMPNS via recvmsg) and the
// sender address. The receive buffer is asked for large (8 MiB by default; SO_RCVBUFFORCE
// when privileged, else SO_RCVBUF, capped by net.core.rmem_max) and the size the kernel
// granted is reported. A datagram longer than the buffer is delivered cut and flagged
// (Chunk::truncated, MSG_TRUNC). IPv4 only.
//
// Who is listened to (issue 14 case 10): the socket binds one local address, by default the
// address of the interface facing the first allowed sender (0.0.0.0 only when configured so).
// Datagrams from senders not on `allowed_senders` are still delivered, flagged
// Chunk::foreign and counted, so the daemon can log them as evidence without ever decoding
// them; they never become the reply target. Write() (External Control frames, Imagenex spec
// §3.2) goes only to the configured `reply_to` head, never to whoever sent last.
//
// Kernel drops (issue 14 case 8): the socket's drop counter (datagrams the kernel discarded
// because the receive buffer was full) is read from the SO_RXQ_OVFL control message of every
// datagram and from SO_MEMINFO on every Read(), and accumulated in kernel_drops().
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
    // Local numeric IPv4 address to bind. "" = the local address the kernel routes towards
    // the first allowed sender (the interface facing the sonar), resolved at every (re)open;
    // needs allowed_senders. "0.0.0.0" (every interface) only when set explicitly.
    std::string bind_address;
    int port = 4040;                         // UDP port, 0..65535 (0 = any, for tests)
    int receive_buffer_bytes = 8 << 20;      // requested SO_RCVBUF, bytes
    std::size_t max_datagram_bytes = 65536;  // receive buffer per datagram, bytes
    bool kernel_timestamps = true;           // SO_TIMESTAMPNS
    BackoffConfig rebind_backoff{};          // retries when bind fails
    // Who may send: "a.b.c.d" (any source port) or "a.b.c.d:port". Datagrams from anyone
    // else are delivered with Chunk::foreign set. Empty = every sender is accepted (tests and
    // benchmarks only: the daemon config requires a list).
    std::vector<std::string> allowed_senders;
    // Where Write() sends: "a.b.c.d" or "a.b.c.d:port"; "" = the first allowed sender. Without
    // a port, the source port of the latest datagram from that address is used (the Delta T
    // topside software listens where it sends from), so the address must be an allowed
    // sender. With neither allowed_senders nor reply_to, the last sender (tests only).
    std::string reply_to;

    std::vector<std::string> Validate() const;
};

// An IPv4 address and port, host byte order.
struct UdpEndpoint {
    std::uint32_t address = 0;
    std::uint16_t port = 0;
    std::string ToString() const;
    // Parses "a.b.c.d:port".
    static std::optional<UdpEndpoint> Parse(const std::string& text);
    // Parses "a.b.c.d" (port 0 = any) or "a.b.c.d:port" (port 1..65535).
    static std::optional<UdpEndpoint> ParseAddressOptionalPort(const std::string& text);
};

class UdpSource final : public ByteSource {
public:
    // Precondition: config.Validate() is empty.
    explicit UdpSource(UdpConfig config);

    Status Open() override;
    // A datagram from a sender not on allowed_senders comes back as kData with
    // chunk.foreign set.
    Expected<ReadOutcome> Read(Chunk& chunk, int timeout_ms) override;
    // Sends `bytes` as one datagram to reply_endpoint(); fails while it is unknown.
    Status Write(std::span<const std::byte> bytes, int timeout_ms) override;
    void Close() override;
    Transport transport() const override { return Transport::kUdp; }
    std::string description() const override;

    // Sends one datagram to `to`.
    Status SendTo(std::span<const std::byte> bytes, const UdpEndpoint& to);
    // The sender of the last allowed datagram, if any (foreign senders never appear here).
    const std::optional<UdpEndpoint>& last_sender() const { return last_sender_; }
    // Where Write() sends now: reply_to (or the first allowed sender) with its configured or
    // learned port; nullopt while the port is not known yet.
    std::optional<UdpEndpoint> reply_endpoint() const;
    // The local address bound ("a.b.c.d"), "" when closed.
    const std::string& bound_address() const { return bound_address_; }
    // The bound port (useful with port 0), 0 when closed.
    int bound_port() const { return bound_port_; }
    // SO_RCVBUF as the kernel reports it after the request (Linux doubles the value it
    // books), bytes; 0 when closed.
    int granted_receive_buffer_bytes() const { return granted_rcvbuf_; }
    // Datagrams that were longer than max_datagram_bytes.
    std::int64_t truncated_datagrams() const { return truncated_; }
    // Datagrams from senders not on allowed_senders.
    std::int64_t foreign_datagrams() const { return foreign_; }

private:
    Status TryOpen();
    bool Allowed(const UdpEndpoint& from) const;
    // Accounts the socket's cumulative drop counter (either source; stale values ignored).
    void NoteDropCounter(std::uint32_t cumulative);
    void PollDropCounter();

    UdpConfig config_;
    detail::UniqueFd fd_;
    Backoff backoff_;
    std::vector<UdpEndpoint> allowed_;  // port 0 = any port
    std::optional<UdpEndpoint> reply_;  // port 0 = learn it; nullopt = last sender
    std::uint16_t reply_port_learned_ = 0;
    std::optional<UdpEndpoint> last_sender_;
    std::string bound_address_;
    int bound_port_ = 0;
    int granted_rcvbuf_ = 0;
    std::int64_t truncated_ = 0;
    std::int64_t foreign_ = 0;
    std::uint32_t drops_seen_ = 0;  // the socket's drop counter already accounted
};

}  // namespace pitmap::acq
