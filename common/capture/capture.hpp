// SPDX-License-Identifier: MIT
// Reading packet captures (.pcap, .pcapng, either gzip-compressed) into reassembled TCP byte
// streams and UDP datagrams, so captured sensor traffic can be framed like a live socket.
//
// Link types: Ethernet (with 802.1Q/802.1ad tags), Linux cooked v1/v2 (SLL, SLL2), raw IP
// (DLT_RAW, LINKTYPE_IPV4/IPV6) and BSD loopback (DLT_NULL/DLT_LOOP). Network: IPv4 and IPv6
// (extension headers skipped). IP fragments are counted, not reassembled. Transport: TCP
// (reassembled per direction, see tcp_reassembler.hpp) and UDP.
//
// Failure: a file that cannot be read or is not a capture is an Error naming the file. Packets
// that cannot be parsed (truncated, unknown link or protocol) are counted in CaptureStats and
// skipped: a capture with bad packets still yields what it can.
// Thread safe: the functions keep no state.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "common/byte_io.hpp"
#include "common/capture/tcp_reassembler.hpp"
#include "common/result.hpp"

namespace pitmap::capture {

// One end of a transport connection.
struct Endpoint {
    std::string address;  // "192.168.1.10" or "fe80::1"
    std::uint16_t port = 0;

    // "192.168.1.10:3001", "[fe80::1]:3001".
    std::string ToString() const;
    friend bool operator==(const Endpoint&, const Endpoint&) = default;
};

// One direction of one TCP connection (source -> destination), reassembled.
struct TcpStream {
    Endpoint src;
    Endpoint dst;
    std::vector<std::uint8_t> bytes;  // the stream as the receiving socket would read it
    std::vector<StreamChunk> chunks;  // when each part of `bytes` became readable
    std::vector<StreamGap> gaps;      // holes in `bytes` (missing from the capture)
    std::int64_t first_utime = 0;     // capture time of its first packet, Unix microseconds
    std::int64_t last_utime = 0;      // capture time of its last packet, Unix microseconds
    TcpStreamStats stats;
};

struct UdpDatagram {
    std::int64_t utime = 0;  // capture time, Unix microseconds
    Endpoint src;
    Endpoint dst;
    std::vector<std::uint8_t> payload;
};

// What was in the capture, packet by packet.
struct CaptureStats {
    std::string format;          // "pcap" or "pcapng"
    bool gzip = false;           // the file was gzip-compressed
    int link_type = -1;          // DLT_* value of the capture
    std::string link_type_name;  // as libpcap names it, e.g. "EN10MB"
    std::uint64_t packets = 0;   // every packet record
    std::uint64_t tcp_packets = 0;
    std::uint64_t udp_packets = 0;
    std::uint64_t non_ip_packets = 0;      // ARP, LLDP, ... (link payload not IPv4/IPv6)
    std::uint64_t other_ip_packets = 0;    // IP but neither TCP nor UDP (ICMP, ...)
    std::uint64_t ip_fragments = 0;        // fragments, not reassembled, payload ignored
    std::uint64_t truncated_packets = 0;   // headers cut short by the snap length or damaged
    std::uint64_t truncated_payloads = 0;  // TCP/UDP payload cut short by the snap length
    std::int64_t first_utime = 0;          // first packet, Unix microseconds (0 if none)
    std::int64_t last_utime = 0;           // last packet, Unix microseconds (0 if none)
    std::string read_error;  // libpcap's message if the file ended inside a record ("" = none);
                             // the packets before it are kept
};

struct CaptureContents {
    std::vector<TcpStream> tcp;    // in order of each direction's first packet
    std::vector<UdpDatagram> udp;  // in capture order
    CaptureStats stats;
};

// The whole file; gzip data (magic 1F 8B) is decompressed, concatenated members included.
// Errors name the file: missing, unreadable, corrupt or truncated gzip data.
Expected<std::vector<std::uint8_t>> ReadFileBytes(const std::string& path);

// True if the file starts with the gzip magic 1F 8B (false if it cannot be read).
bool IsGzipFile(const std::string& path);

// True if `head` starts with a pcap (any byte order, micro- or nanosecond) or pcapng magic.
bool LooksLikeCapture(ByteSpan head);

// Parses a capture held in memory (already decompressed). `name` is used in error messages.
Expected<CaptureContents> ParseCapture(ByteSpan file_bytes, const std::string& name);

// ReadFileBytes + ParseCapture.
Expected<CaptureContents> ReadCapture(const std::string& path);

}  // namespace pitmap::capture
