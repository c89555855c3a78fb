// SPDX-License-Identifier: MIT
// UdpSource hardening (issue 14): kernel drops counted exactly (case 8), allow-listed senders,
// foreign datagrams flagged, replies only to the configured head, default bind address
// (case 10). Loopback only: 127.0.0.2 is a second loopback address on Linux without set-up.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <string>
#include <vector>

#include "firmware_host/io/udp_source.hpp"

namespace pitmap::acq {
namespace {

sockaddr_in Address(const char* ip, int port) {
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<std::uint16_t>(port));
    ::inet_pton(AF_INET, ip, &a.sin_addr);
    return a;
}

// A UDP socket bound to ip:0 (a sonar head, or a forger).
struct Peer {
    int fd = -1;
    int port = 0;
    explicit Peer(const char* ip) {
        fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
        sockaddr_in a = Address(ip, 0);
        EXPECT_EQ(::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof(a)), 0) << ip;
        socklen_t len = sizeof(a);
        ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len);
        port = ntohs(a.sin_port);
    }
    ~Peer() { ::close(fd); }
    Peer(const Peer&) = delete;
    Peer& operator=(const Peer&) = delete;
    void SendTo(int to_port, const std::vector<std::byte>& d) const {
        const sockaddr_in to = Address("127.0.0.1", to_port);
        ASSERT_EQ(
            ::sendto(fd, d.data(), d.size(), 0, reinterpret_cast<const sockaddr*>(&to), sizeof(to)),
            static_cast<long>(d.size()));
    }
    // Datagrams waiting now (non-blocking drain).
    int Pending() const {
        int n = 0;
        std::vector<std::byte> buf(65536);
        while (::recv(fd, buf.data(), buf.size(), MSG_DONTWAIT) >= 0) ++n;
        return n;
    }
    // Waits (bounded) for one datagram; its size, -1 if none came.
    long Receive() const {
        pollfd p{fd, POLLIN, 0};
        if (::poll(&p, 1, 2000) != 1) return -1;
        std::vector<std::byte> buf(65536);
        return ::recv(fd, buf.data(), buf.size(), MSG_DONTWAIT);
    }
};

std::vector<std::byte> Datagram(std::size_t size, int tag) {
    std::vector<std::byte> d(size);
    for (std::size_t k = 0; k < size; ++k) d[k] = static_cast<std::byte>((k + tag) & 0xFF);
    return d;
}

UdpConfig Loopback() {
    UdpConfig c;
    c.bind_address = "127.0.0.1";
    c.port = 0;
    return c;
}

// Issue 14 case 8: a tiny receive buffer, many datagrams sent before anything is read. The
// kernel drops most of them; every one it dropped is counted, so received + dropped == sent.
TEST(UdpSourceHardeningTest, KernelDropsAreCountedExactly) {
    UdpConfig c = Loopback();
    c.receive_buffer_bytes = 16384;  // room for a few datagrams only
    UdpSource src(c);
    ASSERT_TRUE(src.Open().ok()) << src.last_error();
    Peer head("127.0.0.1");
    constexpr int kSent = 400;
    for (int i = 0; i < kSent; ++i) head.SendTo(src.bound_port(), Datagram(1200, i));

    Chunk chunk;
    int received = 0;
    // Drain; loopback delivery is done by the time sendto() returns, the bound only guards
    // against a hang.
    for (int timeouts = 0; timeouts < 20 && received + src.kernel_drops() < kSent;) {
        auto r = src.Read(chunk, 50);
        ASSERT_TRUE(r.ok()) << r.error().message;
        if (*r == ReadOutcome::kData) {
            ++received;
            EXPECT_EQ(chunk.data.size(), 1200u);
        } else {
            ++timeouts;
        }
    }
    std::printf("sent %d, received %d, kernel drops counted %lld\n",
                kSent,
                received,
                static_cast<long long>(src.kernel_drops()));
    EXPECT_GT(received, 0);
    EXPECT_GT(src.kernel_drops(), 0);
    EXPECT_EQ(received + src.kernel_drops(), kSent);

    // One more datagram after the flood: it carries the cumulative counter (SO_RXQ_OVFL);
    // nothing is counted twice.
    head.SendTo(src.bound_port(), Datagram(10, 0));
    auto r = src.Read(chunk, 1000);
    ASSERT_TRUE(r.ok());
    ASSERT_EQ(*r, ReadOutcome::kData);
    EXPECT_EQ(received + src.kernel_drops(), kSent);

    // A reopen starts a new socket; the total keeps what the old one lost.
    const std::int64_t before = src.kernel_drops();
    src.Close();
    ASSERT_TRUE(src.Open().ok());
    EXPECT_EQ(src.kernel_drops(), before);
}

UdpConfig AllowOnly(const std::string& who) {
    UdpConfig c = Loopback();
    c.allowed_senders = {who};
    return c;
}

// Issue 14 case 10: a forger on 127.0.0.2 is flagged foreign, counted, and never becomes the
// reply target; replies go only to the allowed head.
TEST(UdpSourceHardeningTest, ForeignSenderFlaggedAndNeverRepliedTo) {
    UdpSource src(AllowOnly("127.0.0.1"));
    ASSERT_TRUE(src.Open().ok()) << src.last_error();
    Peer head("127.0.0.1");
    Peer forger("127.0.0.2");
    const std::vector<std::byte> ec(256, std::byte{0x45});
    Chunk chunk;

    // The forger speaks first: flagged, counted, and no reply goes anywhere (the head's port
    // is not known yet).
    forger.SendTo(src.bound_port(), Datagram(100, 1));
    auto r = src.Read(chunk, 1000);
    ASSERT_TRUE(r.ok());
    ASSERT_EQ(*r, ReadOutcome::kData);
    EXPECT_TRUE(chunk.foreign);
    EXPECT_EQ(chunk.peer, "127.0.0.2:" + std::to_string(forger.port));
    EXPECT_EQ(chunk.data, Datagram(100, 1));  // delivered unmodified, as evidence
    EXPECT_EQ(src.foreign_datagrams(), 1);
    EXPECT_FALSE(src.last_sender().has_value());
    EXPECT_FALSE(src.Write(ec, 100).ok());
    EXPECT_EQ(forger.Pending(), 0);

    // The head, then the forger again: the reply still goes to the head only.
    head.SendTo(src.bound_port(), Datagram(100, 2));
    forger.SendTo(src.bound_port(), Datagram(100, 3));
    ASSERT_TRUE(src.Read(chunk, 1000).ok());
    EXPECT_FALSE(chunk.foreign);
    ASSERT_TRUE(src.Read(chunk, 1000).ok());
    EXPECT_TRUE(chunk.foreign);
    EXPECT_EQ(src.foreign_datagrams(), 2);
    ASSERT_TRUE(src.last_sender().has_value());
    EXPECT_EQ(src.last_sender()->port, head.port);
    ASSERT_TRUE(src.reply_endpoint().has_value());
    EXPECT_EQ(src.reply_endpoint()->ToString(), "127.0.0.1:" + std::to_string(head.port));
    ASSERT_TRUE(src.Write(ec, 100).ok()) << src.last_error();
    EXPECT_EQ(head.Receive(), 256);
    EXPECT_EQ(forger.Pending(), 0);
}

TEST(UdpSourceHardeningTest, PinnedPortsAndExplicitReplyTo) {
    Peer head("127.0.0.1");
    Peer other("127.0.0.1");  // same address, another port
    UdpConfig c = AllowOnly("127.0.0.1:" + std::to_string(head.port));
    c.reply_to = "127.0.0.1:" + std::to_string(head.port);
    UdpSource src(c);
    ASSERT_TRUE(src.Open().ok());
    // An explicit reply_to port needs no datagram first.
    ASSERT_TRUE(src.Write(std::vector<std::byte>(8, std::byte{1}), 100).ok());
    EXPECT_EQ(head.Receive(), 8);
    other.SendTo(src.bound_port(), Datagram(5, 0));
    Chunk chunk;
    ASSERT_TRUE(src.Read(chunk, 1000).ok());
    EXPECT_TRUE(chunk.foreign);  // the right address but not the pinned port
    head.SendTo(src.bound_port(), Datagram(5, 0));
    ASSERT_TRUE(src.Read(chunk, 1000).ok());
    EXPECT_FALSE(chunk.foreign);
}

// Without bind_address the socket binds the local address facing the first allowed sender,
// not 0.0.0.0.
TEST(UdpSourceHardeningTest, DefaultBindIsTheInterfaceFacingTheSender) {
    UdpConfig c;
    c.port = 0;
    c.allowed_senders = {"127.0.0.1"};
    ASSERT_TRUE(c.Validate().empty());
    UdpSource src(c);
    ASSERT_TRUE(src.Open().ok()) << src.last_error();
    EXPECT_EQ(src.bound_address(), "127.0.0.1");
    EXPECT_NE(src.description().find("127.0.0.1"), std::string::npos);
    // Not reachable on another local address: the socket is not a wildcard.
    Peer p("127.0.0.2");
    const sockaddr_in to = Address("127.0.0.2", src.bound_port());
    const char byte = 1;
    ::sendto(p.fd, &byte, 1, 0, reinterpret_cast<const sockaddr*>(&to), sizeof(to));
    Chunk chunk;
    auto r = src.Read(chunk, 50);
    ASSERT_TRUE(r.ok());
    EXPECT_EQ(*r, ReadOutcome::kTimeout);
}

TEST(UdpSourceHardeningTest, ConfigValidation) {
    UdpConfig c;
    c.port = 4040;
    // No bind address and nobody allowed: nothing to derive the interface from.
    EXPECT_EQ(c.Validate().size(), 1u);
    c.allowed_senders = {"192.168.0.4", "10.0.0.9:4040"};
    EXPECT_TRUE(c.Validate().empty());
    c.allowed_senders = {"sonar", "0.0.0.0", "1.2.3.4:0", "1.2.3.4:70000"};
    EXPECT_EQ(c.Validate().size(), 4u);
    c.allowed_senders = {"192.168.0.4"};
    c.reply_to = "192.168.0.5";  // no port and not an allowed sender: never learnable
    EXPECT_EQ(c.Validate().size(), 1u);
    c.reply_to = "192.168.0.5:4040";
    EXPECT_TRUE(c.Validate().empty());
    c.reply_to = "192.168.0.4";
    EXPECT_TRUE(c.Validate().empty());
    EXPECT_FALSE(UdpEndpoint::ParseAddressOptionalPort("1.2.3.4:").has_value());
    EXPECT_EQ(UdpEndpoint::ParseAddressOptionalPort("1.2.3.4")->port, 0);
    EXPECT_EQ(UdpEndpoint::ParseAddressOptionalPort("1.2.3.4:99")->port, 99);
}

}  // namespace
}  // namespace pitmap::acq
