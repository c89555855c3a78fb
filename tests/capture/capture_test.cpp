// SPDX-License-Identifier: MIT
// pitmap::capture on crafted captures (pcap bytes written here, segment by segment) and on the
// real NovAtel TCP captures in tests/data/novatel.
#include "common/capture/capture.hpp"

#include <gtest/gtest.h>
#include <unistd.h>
#include <zlib.h>

#include <cctype>
#include <cstdio>
#include <filesystem>
#include <ostream>
#include <string>
#include <vector>

#include "common/byte_io.hpp"

namespace pitmap::capture {
namespace {

constexpr int kLinkEthernet = 1;
constexpr int kLinkRaw = 101;  // LINKTYPE_RAW in the file (libpcap maps it to DLT_RAW)
constexpr int kLinkSll = 113;

std::vector<std::uint8_t> Text(const std::string& s) {
    return {s.begin(), s.end()};
}

// Writes the classic pcap format: a 24-byte global header, then 16-byte record headers.
class PcapWriter {
public:
    explicit PcapWriter(int link_type, std::uint32_t snaplen = 65535) {
        ByteWriter w(bytes_);
        w.U32Le(0xA1B2C3D4u);
        w.U16Le(2);
        w.U16Le(4);
        w.U32Le(0);
        w.U32Le(0);
        w.U32Le(snaplen);
        w.U32Le(static_cast<std::uint32_t>(link_type));
    }

    void Packet(std::int64_t utime,
                const std::vector<std::uint8_t>& data,
                std::size_t orig_len = 0) {
        ByteWriter w(bytes_);
        w.U32Le(static_cast<std::uint32_t>(utime / 1000000));
        w.U32Le(static_cast<std::uint32_t>(utime % 1000000));
        w.U32Le(static_cast<std::uint32_t>(data.size()));
        w.U32Le(static_cast<std::uint32_t>(orig_len != 0 ? orig_len : data.size()));
        w.Bytes(data);
    }

    const std::vector<std::uint8_t>& bytes() const { return bytes_; }

private:
    std::vector<std::uint8_t> bytes_;
};

struct Tuple {
    std::uint32_t src_ip = 0xC0A80002;  // 192.168.0.2
    std::uint16_t src_port = 3001;
    std::uint32_t dst_ip = 0xC0A80001;  // 192.168.0.1
    std::uint16_t dst_port = 50000;
};

constexpr std::uint8_t kFin = 0x01;
constexpr std::uint8_t kSyn = 0x02;
constexpr std::uint8_t kAck = 0x10;

std::vector<std::uint8_t> Ipv4(const Tuple& t,
                               std::uint8_t proto,
                               const std::vector<std::uint8_t>& l4,
                               std::uint16_t frag = 0) {
    std::vector<std::uint8_t> out;
    ByteWriter w(out);
    w.U8(0x45);
    w.U8(0);
    w.U16Be(static_cast<std::uint16_t>(20 + l4.size()));
    w.U16Be(0);
    w.U16Be(frag);
    w.U8(64);
    w.U8(proto);
    w.U16Be(0);
    w.U32Be(t.src_ip);
    w.U32Be(t.dst_ip);
    w.Bytes(l4);
    return out;
}

std::vector<std::uint8_t> Tcp(const Tuple& t,
                              std::uint32_t seq,
                              std::uint8_t flags,
                              const std::vector<std::uint8_t>& payload) {
    std::vector<std::uint8_t> out;
    ByteWriter w(out);
    w.U16Be(t.src_port);
    w.U16Be(t.dst_port);
    w.U32Be(seq);
    w.U32Be(0);
    w.U8(0x50);
    w.U8(flags);
    w.U16Be(65535);
    w.U16Be(0);
    w.U16Be(0);
    w.Bytes(payload);
    return Ipv4(t, 6, out);
}

std::vector<std::uint8_t> Udp(const Tuple& t, const std::vector<std::uint8_t>& payload) {
    std::vector<std::uint8_t> out;
    ByteWriter w(out);
    w.U16Be(t.src_port);
    w.U16Be(t.dst_port);
    w.U16Be(static_cast<std::uint16_t>(8 + payload.size()));
    w.U16Be(0);
    w.Bytes(payload);
    return Ipv4(t, 17, out);
}

std::vector<std::uint8_t> Ethernet(const std::vector<std::uint8_t>& ip,
                                   bool vlan = false,
                                   std::size_t pad_to = 0) {
    std::vector<std::uint8_t> out(12, 0x11);
    ByteWriter w(out);
    if (vlan) {
        w.U16Be(0x8100);
        w.U16Be(7);
    }
    w.U16Be(0x0800);
    w.Bytes(ip);
    if (out.size() < pad_to) out.resize(pad_to, 0);  // Ethernet minimum-length padding
    return out;
}

std::vector<std::uint8_t> Sll(const std::vector<std::uint8_t>& ip) {
    std::vector<std::uint8_t> out;
    ByteWriter w(out);
    w.U16Be(0);  // packet type: to us
    w.U16Be(1);  // ARPHRD_ETHER
    w.U16Be(6);
    w.Zeros(8);
    w.U16Be(0x0800);
    w.Bytes(ip);
    return out;
}

CaptureContents Parse(const PcapWriter& w) {
    auto c = ParseCapture(w.bytes(), "crafted.pcap");
    EXPECT_TRUE(c.ok()) << (c.ok() ? "" : c.error().message);
    return c.ok() ? std::move(c).value() : CaptureContents{};
}

// "0123456789abcdefghij..." cut into segments.
const std::string kData = "0123456789abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ";
constexpr std::uint32_t kIsn = 1000;  // SYN sequence number; data starts at kIsn + 1

std::vector<std::uint8_t> Part(std::size_t from, std::size_t n) {
    return Text(kData.substr(from, n));
}

TEST(CaptureTest, InOrderSegmentsWithSynAndFin) {
    PcapWriter w(kLinkEthernet);
    Tuple t;
    w.Packet(1'000'000, Ethernet(Tcp(t, kIsn, kSyn, {})));
    w.Packet(1'000'100, Ethernet(Tcp(t, kIsn + 1, kAck, Part(0, 10))));
    w.Packet(1'000'200, Ethernet(Tcp(t, kIsn + 11, kAck, Part(10, 20))));
    w.Packet(1'000'300, Ethernet(Tcp(t, kIsn + 31, kAck | kFin, Part(30, 5))));
    const auto c = Parse(w);
    ASSERT_EQ(c.tcp.size(), 1u);
    const auto& s = c.tcp[0];
    EXPECT_EQ(std::string(s.bytes.begin(), s.bytes.end()), kData.substr(0, 35));
    EXPECT_EQ(s.src.ToString(), "192.168.0.2:3001");
    EXPECT_EQ(s.dst.ToString(), "192.168.0.1:50000");
    EXPECT_EQ(s.first_utime, 1'000'000);
    EXPECT_EQ(s.last_utime, 1'000'300);
    EXPECT_TRUE(s.stats.syn_seen);
    EXPECT_TRUE(s.stats.fin_seen);
    EXPECT_EQ(s.stats.packets, 4u);
    EXPECT_EQ(s.stats.payload_segments, 3u);
    EXPECT_EQ(s.stats.retransmitted_segments, 0u);
    EXPECT_EQ(s.stats.gap_bytes, 0u);
    ASSERT_EQ(s.chunks.size(), 3u);
    EXPECT_EQ(s.chunks[1].offset, 10u);
    EXPECT_EQ(s.chunks[1].utime, 1'000'200);
    EXPECT_EQ(c.stats.packets, 4u);
    EXPECT_EQ(c.stats.tcp_packets, 4u);
    EXPECT_EQ(c.stats.format, "pcap");
    EXPECT_EQ(c.stats.link_type_name, "EN10MB");
}

TEST(CaptureTest, EthernetPaddingIsNotPayload) {
    PcapWriter w(kLinkEthernet);
    Tuple t;
    // 14 + 20 + 20 + 2 = 56 bytes, padded to the 60-byte Ethernet minimum.
    w.Packet(1, Ethernet(Tcp(t, kIsn + 1, kAck, Part(0, 2)), false, 60));
    w.Packet(2, Ethernet(Tcp(t, kIsn + 3, kAck, Part(2, 3)), true, 60));
    const auto c = Parse(w);
    ASSERT_EQ(c.tcp.size(), 1u);
    EXPECT_EQ(std::string(c.tcp[0].bytes.begin(), c.tcp[0].bytes.end()), "01234");
}

TEST(CaptureTest, OutOfOrderSegmentsAreReordered) {
    PcapWriter w(kLinkEthernet);
    Tuple t;
    w.Packet(10, Ethernet(Tcp(t, kIsn, kSyn, {})));
    w.Packet(20, Ethernet(Tcp(t, kIsn + 21, kAck, Part(20, 10))));
    w.Packet(30, Ethernet(Tcp(t, kIsn + 11, kAck, Part(10, 10))));
    w.Packet(40, Ethernet(Tcp(t, kIsn + 1, kAck, Part(0, 10))));
    const auto c = Parse(w);
    ASSERT_EQ(c.tcp.size(), 1u);
    const auto& s = c.tcp[0];
    EXPECT_EQ(std::string(s.bytes.begin(), s.bytes.end()), kData.substr(0, 30));
    EXPECT_EQ(s.stats.out_of_order_segments, 2u);
    EXPECT_EQ(s.stats.retransmitted_segments, 0u);
    EXPECT_EQ(s.stats.gaps, 0u);
    // Everything became readable when the first segment arrived.
    for (const auto& chunk : s.chunks) EXPECT_EQ(chunk.utime, 40);
}

TEST(CaptureTest, OutOfOrderWithoutSynStartsAtLowestSequence) {
    PcapWriter w(kLinkEthernet);
    Tuple t;
    w.Packet(1, Ethernet(Tcp(t, 5010, kAck, Part(10, 10))));
    w.Packet(2, Ethernet(Tcp(t, 5000, kAck, Part(0, 10))));
    const auto c = Parse(w);
    ASSERT_EQ(c.tcp.size(), 1u);
    EXPECT_EQ(std::string(c.tcp[0].bytes.begin(), c.tcp[0].bytes.end()), kData.substr(0, 20));
    EXPECT_FALSE(c.tcp[0].stats.syn_seen);
    EXPECT_EQ(c.tcp[0].stats.out_of_order_segments, 1u);
}

TEST(CaptureTest, RetransmissionsAreCountedNotDuplicated) {
    PcapWriter w(kLinkEthernet);
    Tuple t;
    w.Packet(1, Ethernet(Tcp(t, kIsn + 1, kAck, Part(0, 10))));
    w.Packet(2, Ethernet(Tcp(t, kIsn + 11, kAck, Part(10, 10))));
    w.Packet(3, Ethernet(Tcp(t, kIsn + 11, kAck, Part(10, 10))));  // resent
    w.Packet(4, Ethernet(Tcp(t, kIsn + 11, kAck, Part(10, 10))));  // resent again
    w.Packet(5, Ethernet(Tcp(t, kIsn + 21, kAck, Part(20, 5))));
    w.Packet(6, Ethernet(Tcp(t, kIsn + 1, kAck, Part(0, 10))));  // very late resend
    const auto c = Parse(w);
    ASSERT_EQ(c.tcp.size(), 1u);
    const auto& s = c.tcp[0];
    EXPECT_EQ(std::string(s.bytes.begin(), s.bytes.end()), kData.substr(0, 25));
    EXPECT_EQ(s.stats.retransmitted_segments, 3u);
    EXPECT_EQ(s.stats.retransmitted_bytes, 30u);
    EXPECT_EQ(s.stats.payload_bytes, 55u);
    EXPECT_EQ(s.stats.overlapping_segments, 0u);
}

TEST(CaptureTest, OverlappingSegmentsKeepOnlyNewBytes) {
    PcapWriter w(kLinkEthernet);
    Tuple t;
    w.Packet(1, Ethernet(Tcp(t, kIsn + 1, kAck, Part(0, 10))));
    w.Packet(2, Ethernet(Tcp(t, kIsn + 6, kAck, Part(5, 10))));    // 5 old + 5 new
    w.Packet(3, Ethernet(Tcp(t, kIsn + 26, kAck, Part(25, 10))));  // ahead of a hole
    w.Packet(4, Ethernet(Tcp(t, kIsn + 16, kAck, Part(15, 15))));  // fills it, 5 overlap
    const auto c = Parse(w);
    ASSERT_EQ(c.tcp.size(), 1u);
    const auto& s = c.tcp[0];
    EXPECT_EQ(std::string(s.bytes.begin(), s.bytes.end()), kData.substr(0, 35));
    // Segment 2 resent 5 bytes; the waiting segment 3 repeats 5 bytes of segment 4.
    EXPECT_EQ(s.stats.overlapping_segments, 2u);
    EXPECT_EQ(s.stats.retransmitted_segments, 2u);
    EXPECT_EQ(s.stats.out_of_order_segments, 1u);
    EXPECT_EQ(s.stats.retransmitted_bytes, 10u);
}

TEST(CaptureTest, GapIsReportedAndBytesAfterItKept) {
    PcapWriter w(kLinkEthernet);
    Tuple t;
    w.Packet(1, Ethernet(Tcp(t, kIsn, kSyn, {})));
    w.Packet(2, Ethernet(Tcp(t, kIsn + 1, kAck, Part(0, 10))));
    // Bytes 10..19 never captured.
    w.Packet(3, Ethernet(Tcp(t, kIsn + 21, kAck, Part(20, 10))));
    w.Packet(4, Ethernet(Tcp(t, kIsn + 31, kAck, Part(30, 10))));
    const auto c = Parse(w);
    ASSERT_EQ(c.tcp.size(), 1u);
    const auto& s = c.tcp[0];
    EXPECT_EQ(std::string(s.bytes.begin(), s.bytes.end()),
              kData.substr(0, 10) + kData.substr(20, 20));
    EXPECT_EQ(s.stats.gaps, 1u);
    EXPECT_EQ(s.stats.gap_bytes, 10u);
    ASSERT_EQ(s.gaps.size(), 1u);
    EXPECT_EQ(s.gaps[0].offset, 10u);
    EXPECT_EQ(s.gaps[0].missing_bytes, 10u);
}

TEST(CaptureTest, SequenceNumbersWrapAround) {
    PcapWriter w(kLinkEthernet);
    Tuple t;
    const std::uint32_t isn = 0xFFFFFFF0u;
    w.Packet(1, Ethernet(Tcp(t, isn, kSyn, {})));
    w.Packet(2, Ethernet(Tcp(t, isn + 1, kAck, Part(0, 20))));  // wraps
    w.Packet(3, Ethernet(Tcp(t, static_cast<std::uint32_t>(isn + 21), kAck, Part(20, 10))));
    const auto c = Parse(w);
    ASSERT_EQ(c.tcp.size(), 1u);
    EXPECT_EQ(std::string(c.tcp[0].bytes.begin(), c.tcp[0].bytes.end()), kData.substr(0, 30));
    EXPECT_EQ(c.tcp[0].stats.gaps, 0u);
}

TEST(CaptureTest, TwoDirectionsAndTwoConnectionsAreSeparateStreams) {
    PcapWriter w(kLinkEthernet);
    Tuple a;
    Tuple back{a.dst_ip, a.dst_port, a.src_ip, a.src_port};
    Tuple b = a;
    b.dst_port = 50001;
    w.Packet(1, Ethernet(Tcp(a, 100, kAck, Text("abc"))));
    w.Packet(2, Ethernet(Tcp(back, 900, kAck, Text("LOG BESTPOSB\r\n"))));
    w.Packet(3, Ethernet(Tcp(b, 7000, kAck, Text("xyz"))));
    w.Packet(4, Ethernet(Tcp(a, 103, kAck, Text("def"))));
    w.Packet(5, Ethernet(Tcp(b, 7003, kAck, Text("uvw"))));
    const auto c = Parse(w);
    ASSERT_EQ(c.tcp.size(), 3u);
    EXPECT_EQ(std::string(c.tcp[0].bytes.begin(), c.tcp[0].bytes.end()), "abcdef");
    EXPECT_EQ(std::string(c.tcp[1].bytes.begin(), c.tcp[1].bytes.end()), "LOG BESTPOSB\r\n");
    EXPECT_EQ(c.tcp[1].src.port, 50000);
    EXPECT_EQ(std::string(c.tcp[2].bytes.begin(), c.tcp[2].bytes.end()), "xyzuvw");
    EXPECT_EQ(c.tcp[2].dst.port, 50001);
}

TEST(CaptureTest, ReusedTupleAfterFinStartsANewStream) {
    PcapWriter w(kLinkEthernet);
    Tuple t;
    w.Packet(1, Ethernet(Tcp(t, 100, kSyn, {})));
    w.Packet(2, Ethernet(Tcp(t, 101, kAck | kFin, Text("one"))));
    w.Packet(3, Ethernet(Tcp(t, 90000, kSyn, {})));
    w.Packet(4, Ethernet(Tcp(t, 90001, kAck, Text("two"))));
    const auto c = Parse(w);
    ASSERT_EQ(c.tcp.size(), 2u);
    EXPECT_EQ(std::string(c.tcp[0].bytes.begin(), c.tcp[0].bytes.end()), "one");
    EXPECT_EQ(std::string(c.tcp[1].bytes.begin(), c.tcp[1].bytes.end()), "two");
}

TEST(CaptureTest, UdpDatagramsKeepBoundariesAndTimes) {
    PcapWriter w(kLinkEthernet);
    Tuple t{0x0A000002, 4040, 0x0A000001, 4040};
    w.Packet(1'500'000, Ethernet(Udp(t, Text("83P first"))));
    w.Packet(1'600'000, Ethernet(Udp(t, Text("83P second")), false, 60));
    const auto c = Parse(w);
    EXPECT_TRUE(c.tcp.empty());
    ASSERT_EQ(c.udp.size(), 2u);
    EXPECT_EQ(c.udp[0].utime, 1'500'000);
    EXPECT_EQ(std::string(c.udp[0].payload.begin(), c.udp[0].payload.end()), "83P first");
    EXPECT_EQ(std::string(c.udp[1].payload.begin(), c.udp[1].payload.end()), "83P second");
    EXPECT_EQ(c.udp[1].src.ToString(), "10.0.0.2:4040");
    EXPECT_EQ(c.stats.udp_packets, 2u);
}

TEST(CaptureTest, LinuxCookedAndRawIpLinkTypes) {
    Tuple t;
    PcapWriter sll(kLinkSll);
    sll.Packet(1, Sll(Tcp(t, 1, kAck, Text("sll"))));
    const auto a = Parse(sll);
    ASSERT_EQ(a.tcp.size(), 1u);
    EXPECT_EQ(std::string(a.tcp[0].bytes.begin(), a.tcp[0].bytes.end()), "sll");
    EXPECT_EQ(a.stats.link_type_name, "LINUX_SLL");

    PcapWriter raw(kLinkRaw);
    raw.Packet(1, Udp(t, Text("raw")));
    const auto b = Parse(raw);
    ASSERT_EQ(b.udp.size(), 1u);
    EXPECT_EQ(std::string(b.udp[0].payload.begin(), b.udp[0].payload.end()), "raw");
}

TEST(CaptureTest, Ipv6Udp) {
    PcapWriter w(kLinkRaw);
    std::vector<std::uint8_t> pkt;
    ByteWriter bw(pkt);
    bw.U32Be(0x60000000);
    bw.U16Be(8 + 4);
    bw.U8(17);
    bw.U8(64);
    bw.Zeros(15);
    bw.U8(1);  // ::1
    bw.Zeros(15);
    bw.U8(2);  // ::2
    bw.U16Be(1234);
    bw.U16Be(4040);
    bw.U16Be(12);
    bw.U16Be(0);
    bw.Bytes(Text("ping"));
    w.Packet(1, pkt);
    const auto c = Parse(w);
    ASSERT_EQ(c.udp.size(), 1u);
    EXPECT_EQ(c.udp[0].src.ToString(), "[::1]:1234");
    EXPECT_EQ(std::string(c.udp[0].payload.begin(), c.udp[0].payload.end()), "ping");
}

TEST(CaptureTest, BadPacketsAreCountedNotFatal) {
    PcapWriter w(kLinkEthernet);
    Tuple t;
    w.Packet(1, {0x01, 0x02, 0x03});  // shorter than an Ethernet header
    std::vector<std::uint8_t> arp(12, 0);
    arp.push_back(0x08);
    arp.push_back(0x06);
    arp.resize(42, 0);
    w.Packet(2, arp);
    w.Packet(3, Ethernet(Ipv4(t, 1, {8, 0, 0, 0})));                            // ICMP
    w.Packet(4, Ethernet(Ipv4(t, 17, {0, 1, 0, 2, 0, 9, 0, 0, 'x'}, 0x2000)));  // fragment
    auto snapped = Ethernet(Tcp(t, 1, kAck, Text("0123456789")));
    const std::size_t full = snapped.size();
    snapped.resize(full - 4);
    w.Packet(5, snapped, full);  // the snap length cut 4 payload bytes
    const auto c = Parse(w);
    EXPECT_EQ(c.stats.packets, 5u);
    EXPECT_EQ(c.stats.truncated_packets, 1u);
    EXPECT_EQ(c.stats.non_ip_packets, 1u);
    EXPECT_EQ(c.stats.other_ip_packets, 1u);
    EXPECT_EQ(c.stats.ip_fragments, 1u);
    EXPECT_EQ(c.stats.truncated_payloads, 1u);
    ASSERT_EQ(c.tcp.size(), 1u);
    EXPECT_EQ(std::string(c.tcp[0].bytes.begin(), c.tcp[0].bytes.end()), "012345");
}

TEST(CaptureTest, TruncatedFileKeepsEarlierPackets) {
    PcapWriter w(kLinkEthernet);
    Tuple t;
    w.Packet(1, Ethernet(Tcp(t, 1, kAck, Text("whole"))));
    w.Packet(2, Ethernet(Tcp(t, 6, kAck, Text("cut"))));
    auto bytes = w.bytes();
    bytes.resize(bytes.size() - 5);
    const auto c = ParseCapture(bytes, "cut.pcap");
    ASSERT_TRUE(c.ok()) << c.error().message;
    EXPECT_FALSE(c->stats.read_error.empty());
    ASSERT_EQ(c->tcp.size(), 1u);
    EXPECT_EQ(std::string(c->tcp[0].bytes.begin(), c->tcp[0].bytes.end()), "whole");
}

TEST(CaptureTest, GarbageAndMissingFilesAreErrorsNamingTheFile) {
    const std::vector<std::uint8_t> garbage = Text("this is not a capture at all");
    auto a = ParseCapture(garbage, "garbage.bin");
    ASSERT_FALSE(a.ok());
    EXPECT_NE(a.error().message.find("garbage.bin"), std::string::npos);

    // The right magic, then nonsense: libpcap rejects it, we report it.
    std::vector<std::uint8_t> bad_header = {0xD4, 0xC3, 0xB2, 0xA1, 0x09, 0x00};
    auto b = ParseCapture(bad_header, "short.pcap");
    ASSERT_FALSE(b.ok());
    EXPECT_NE(b.error().message.find("short.pcap"), std::string::npos);

    auto c = ReadCapture("no/such/file.pcap");
    ASSERT_FALSE(c.ok());
    EXPECT_NE(c.error().message.find("no/such/file.pcap"), std::string::npos);

    PcapWriter usb(189);  // LINKTYPE_USB_LINUX: not a network we read
    usb.Packet(1, {1, 2, 3});
    auto d = ParseCapture(usb.bytes(), "usb.pcap");
    ASSERT_FALSE(d.ok());
    EXPECT_NE(d.error().message.find("unsupported link type"), std::string::npos);
}

class TempFile {
public:
    explicit TempFile(const std::string& name)
        : path_((std::filesystem::temp_directory_path() / (std::to_string(::getpid()) + "_" + name))
                    .string()) {}
    ~TempFile() { std::remove(path_.c_str()); }
    const std::string& path() const { return path_; }

private:
    std::string path_;
};

TEST(CaptureTest, GzippedCaptureFromFile) {
    PcapWriter w(kLinkEthernet);
    Tuple t;
    w.Packet(1, Ethernet(Tcp(t, 1, kAck, Text("compressed"))));
    TempFile file("capture_test.pcap.gz");
    gzFile gz = gzopen(file.path().c_str(), "wb");
    ASSERT_NE(gz, nullptr);
    ASSERT_EQ(gzwrite(gz, w.bytes().data(), static_cast<unsigned>(w.bytes().size())),
              static_cast<int>(w.bytes().size()));
    ASSERT_EQ(gzclose(gz), Z_OK);

    const auto bytes = ReadFileBytes(file.path());
    ASSERT_TRUE(bytes.ok()) << bytes.error().message;
    EXPECT_EQ(*bytes, w.bytes());
    const auto c = ReadCapture(file.path());
    ASSERT_TRUE(c.ok()) << c.error().message;
    EXPECT_TRUE(c->stats.gzip);
    ASSERT_EQ(c->tcp.size(), 1u);
    EXPECT_EQ(std::string(c->tcp[0].bytes.begin(), c->tcp[0].bytes.end()), "compressed");

    // Cut the compressed file short: an error naming the file, not a crash.
    std::FILE* f = std::fopen(file.path().c_str(), "rb");
    ASSERT_NE(f, nullptr);
    std::vector<std::uint8_t> gz_bytes(4096);
    gz_bytes.resize(std::fread(gz_bytes.data(), 1, gz_bytes.size(), f));
    std::fclose(f);
    gz_bytes.resize(gz_bytes.size() / 2);
    f = std::fopen(file.path().c_str(), "wb");
    ASSERT_NE(f, nullptr);
    std::fwrite(gz_bytes.data(), 1, gz_bytes.size(), f);
    std::fclose(f);
    const auto cut = ReadFileBytes(file.path());
    ASSERT_FALSE(cut.ok());
    EXPECT_NE(cut.error().message.find(file.path()), std::string::npos);
    EXPECT_NE(cut.error().message.find("truncated"), std::string::npos);
}

// Reference values for the real captures, computed independently of this library (a short
// script walking the pcap records): the receiver's direction carries payload segments whose
// byte ranges cover [first sequence number, end) without holes; the stream length is the size
// of that union, the payload total counts every captured byte.
struct RealCapture {
    const char* file;
    const char* format;
    std::uint64_t stream_bytes;   // union of the segments' byte ranges
    std::uint64_t payload_bytes;  // every payload byte captured
    std::uint64_t payload_segments;
    std::uint64_t retransmitted_segments;
    const char* first_bytes;  // the stream starts with a prompt or a binary sync
};

void PrintTo(const RealCapture& capture, std::ostream* os) {
    *os << capture.file;
}

class CaptureRealTest : public ::testing::TestWithParam<RealCapture> {};

TEST_P(CaptureRealTest, ReassembledStreamMatchesReference) {
    const RealCapture& ref = GetParam();
    const auto c = ReadCapture(std::string(PITMAP_TEST_DATA_DIR) + "/novatel/" + ref.file);
    ASSERT_TRUE(c.ok()) << c.error().message;
    EXPECT_EQ(c->stats.format, ref.format);
    EXPECT_TRUE(c->stats.read_error.empty()) << c->stats.read_error;
    EXPECT_TRUE(c->udp.empty());
    const TcpStream* rx = nullptr;
    for (const auto& s : c->tcp) {
        if (!s.bytes.empty()) {
            ASSERT_EQ(rx, nullptr) << "more than one direction carries data";
            rx = &s;
        }
    }
    ASSERT_NE(rx, nullptr);
    EXPECT_EQ(rx->src.port, 3001);  // the receiver's ICOM1 port
    EXPECT_EQ(rx->bytes.size(), ref.stream_bytes);
    EXPECT_EQ(rx->stats.payload_bytes, ref.payload_bytes);
    EXPECT_EQ(rx->stats.payload_segments, ref.payload_segments);
    EXPECT_EQ(rx->stats.retransmitted_segments, ref.retransmitted_segments);
    EXPECT_EQ(rx->bytes.size() + rx->stats.retransmitted_bytes, rx->stats.payload_bytes);
    EXPECT_EQ(rx->stats.gaps, 0u);
    EXPECT_EQ(rx->stats.out_of_order_segments, 0u);
    const std::string head(ref.first_bytes);
    ASSERT_GE(rx->bytes.size(), head.size());
    EXPECT_EQ(std::string(rx->bytes.begin(), rx->bytes.begin() + static_cast<long>(head.size())),
              head);
}

INSTANTIATE_TEST_SUITE_P(
    Novatel,
    CaptureRealTest,
    ::testing::Values(
        // Ten retransmissions resend a 60-byte PSRDOP2 segment together with the next 180
        // bytes: 600 duplicate bytes, 8527 - 600 = 7927 in the stream.
        RealCapture{"swri_bestpos-bestvel-psrdop2-sync.pcap",
                    "pcap",
                    7927,
                    8527,
                    66,
                    10,
                    "[ICOM1]\xAA\x44\x12"},
        RealCapture{
            "swri_corrimudata.pcapng", "pcapng", 10872, 10872, 100, 0, "\r\n<OK\r\n[ICOM1]"},
        RealCapture{"spandrv_propak6-basic-fix.pcap.gz",
                    "pcap",
                    1527600,
                    1527600,
                    10051,
                    0,
                    "\xAA\x44\x12"},
        RealCapture{"spandrv_propak6-ins-ppp.pcap.gz",
                    "pcap",
                    864872,
                    864872,
                    8191,
                    0,
                    "\r\n<OK\r\n[ICOM1]"}),
    [](const ::testing::TestParamInfo<RealCapture>& param_info) {
        std::string name = param_info.param.file;
        for (char& ch : name) {
            if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
        }
        return name;
    });

}  // namespace
}  // namespace pitmap::capture
