// SPDX-License-Identifier: MIT
// TcpClientSource and UdpSource on 127.0.0.1 only.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <string>
#include <vector>

#include "firmware_host/io/tcp_client_source.hpp"
#include "firmware_host/io/udp_source.hpp"

namespace pitmap::acq {
namespace {

sockaddr_in Loopback(int port) {
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<std::uint16_t>(port));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    return a;
}

// A listening TCP server on 127.0.0.1 (port 0 = any free port).
struct Server {
    int listen_fd = -1;
    int port = 0;
    bool Listen(int want_port) {
        listen_fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
        const int one = 1;
        ::setsockopt(listen_fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof(one));
        sockaddr_in a = Loopback(want_port);
        if (::bind(listen_fd, reinterpret_cast<sockaddr*>(&a), sizeof(a)) != 0) return false;
        if (::listen(listen_fd, 4) != 0) return false;
        socklen_t len = sizeof(a);
        ::getsockname(listen_fd, reinterpret_cast<sockaddr*>(&a), &len);
        port = ntohs(a.sin_port);
        return true;
    }
    int Accept(int timeout_ms) {
        pollfd p{listen_fd, POLLIN, 0};
        if (::poll(&p, 1, timeout_ms) != 1) return -1;
        return ::accept4(listen_fd, nullptr, nullptr, SOCK_CLOEXEC);
    }
    void Close() {
        if (listen_fd >= 0) ::close(listen_fd);
        listen_fd = -1;
    }
    ~Server() { Close(); }
};

std::vector<std::byte> Bytes(const std::string& s) {
    std::vector<std::byte> v;
    for (char c : s) v.push_back(static_cast<std::byte>(c));
    return v;
}

std::vector<std::byte> ReadAtLeast(ByteSource& src, std::size_t n, Chunk* last = nullptr) {
    std::vector<std::byte> got;
    Chunk chunk;
    for (int i = 0; i < 100 && got.size() < n; ++i) {
        auto r = src.Read(chunk, 50);
        if (r.ok() && *r == ReadOutcome::kData) {
            got.insert(got.end(), chunk.data.begin(), chunk.data.end());
            if (last != nullptr) *last = chunk;
        }
    }
    return got;
}

TcpClientConfig TcpConfig(int port) {
    TcpClientConfig c;
    c.host = "127.0.0.1";
    c.port = port;
    c.connect_timeout_ms = 500;
    c.reconnect_backoff = {.initial_ms = 10, .max_ms = 40, .factor = 2.0};
    return c;
}

TEST(TcpClientSourceTest, ReadsWritesAndReconnectsAfterServerRestart) {
    Server server;
    ASSERT_TRUE(server.Listen(0));
    TcpClientSource src(TcpConfig(server.port));
    ASSERT_TRUE(src.Open().ok()) << src.last_error();
    int conn = server.Accept(1000);
    ASSERT_GE(conn, 0);
    const auto prompt = Bytes("[ICOM1]\xAA\x44\x12\x1C");
    ASSERT_EQ(::write(conn, prompt.data(), prompt.size()), static_cast<long>(prompt.size()));
    Chunk last;
    EXPECT_EQ(ReadAtLeast(src, prompt.size(), &last), prompt);
    EXPECT_EQ(last.peer, "127.0.0.1:" + std::to_string(server.port));
    EXPECT_GE(last.utime_kernel, 0);  // TCP kernel stamps are best effort (0 = none)

    const auto cmd = Bytes("LOG INSPVASB ONTIME 0.02\r\n");
    ASSERT_TRUE(src.Write(cmd, 500).ok());
    std::vector<std::byte> got(cmd.size());
    ASSERT_EQ(::recv(conn, got.data(), got.size(), MSG_WAITALL), static_cast<long>(cmd.size()));
    EXPECT_EQ(got, cmd);

    // The server goes away: the source notices and reconnects once it is back.
    ::close(conn);
    const int port = server.port;
    server.Close();
    Chunk chunk;
    bool lost = false;
    for (int i = 0; i < 50 && !lost; ++i) lost = !src.Read(chunk, 20).ok();
    ASSERT_TRUE(lost);
    EXPECT_EQ(src.state(), SourceState::kDisconnected);
    for (int i = 0; i < 3; ++i) (void)src.Read(chunk, 20);  // refused, with backoff

    Server again;
    ASSERT_TRUE(again.Listen(port));
    int conn2 = -1;
    for (int i = 0; i < 100 && conn2 < 0; ++i) {
        (void)src.Read(chunk, 10);
        conn2 = again.Accept(0);
    }
    ASSERT_GE(conn2, 0);
    const auto more = Bytes("<OK\r\n");
    ASSERT_EQ(::write(conn2, more.data(), more.size()), 5);
    EXPECT_EQ(ReadAtLeast(src, more.size()), more);
    EXPECT_EQ(src.reconnects(), 1);
    EXPECT_EQ(src.generation(), 2);
    ::close(conn2);
}

TEST(TcpClientSourceTest, RefusedConnectIsAnErrorValue) {
    Server server;
    ASSERT_TRUE(server.Listen(0));
    const int port = server.port;
    server.Close();
    TcpClientSource src(TcpConfig(port));
    auto s = src.Open();
    ASSERT_FALSE(s.ok());
    EXPECT_NE(s.error().message.find("refused"), std::string::npos) << s.error().message;
    EXPECT_FALSE(src.Write(Bytes("x"), 10).ok());
}

TEST(TcpClientSourceTest, ConfigValidation) {
    TcpClientConfig c;
    EXPECT_EQ(c.Validate().size(), 1u);  // host missing
    c.host = "127.0.0.1";
    c.port = 70000;
    c.keepalive_count = 0;
    EXPECT_EQ(c.Validate().size(), 2u);
}

UdpConfig UdpLoopback() {
    UdpConfig c;
    c.bind_address = "127.0.0.1";
    c.port = 0;
    return c;
}

TEST(UdpSourceTest, DatagramsWithKernelTimestampsAndReplies) {
    UdpSource src(UdpLoopback());
    ASSERT_TRUE(src.Open().ok()) << src.last_error();
    ASSERT_GT(src.bound_port(), 0);
    EXPECT_GE(src.granted_receive_buffer_bytes(), 1 << 20);
    std::printf("UDP receive buffer granted: %d bytes\n", src.granted_receive_buffer_bytes());

    const int tx = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    sockaddr_in tx_addr = Loopback(0);
    ASSERT_EQ(::bind(tx, reinterpret_cast<sockaddr*>(&tx_addr), sizeof(tx_addr)), 0);
    socklen_t len = sizeof(tx_addr);
    ::getsockname(tx, reinterpret_cast<sockaddr*>(&tx_addr), &len);
    const sockaddr_in dst = Loopback(src.bound_port());

    // Three datagrams, the second one larger than an Ethernet MTU (fragmented 83P).
    std::vector<std::vector<std::byte>> sent;
    for (std::size_t size : {100u, 2176u, 1u}) {
        std::vector<std::byte> d(size);
        for (std::size_t k = 0; k < size; ++k) d[k] = static_cast<std::byte>((k * 7 + size) & 0xFF);
        ASSERT_EQ(
            ::sendto(
                tx, d.data(), d.size(), 0, reinterpret_cast<const sockaddr*>(&dst), sizeof(dst)),
            static_cast<long>(size));
        sent.push_back(d);
    }
    Chunk chunk;
    for (const auto& d : sent) {
        auto r = src.Read(chunk, 1000);
        ASSERT_TRUE(r.ok());
        ASSERT_EQ(*r, ReadOutcome::kData);
        EXPECT_EQ(chunk.data, d);  // one datagram per chunk
        EXPECT_FALSE(chunk.truncated);
        EXPECT_GT(chunk.utime_kernel, 0);
        EXPECT_LE(chunk.utime_kernel, chunk.utime_host);
        EXPECT_EQ(chunk.peer, "127.0.0.1:" + std::to_string(ntohs(tx_addr.sin_port)));
    }
    ASSERT_TRUE(src.last_sender().has_value());
    EXPECT_EQ(src.last_sender()->ToString(), chunk.peer);

    // Reply to the sender (an External Control frame in the daemon).
    std::vector<std::byte> ec(256, std::byte{0});
    ec[0] = std::byte{'E'};
    ec[1] = std::byte{'C'};
    ASSERT_TRUE(src.Write(ec, 100).ok());
    std::vector<std::byte> back(512);
    pollfd p{tx, POLLIN, 0};
    ASSERT_EQ(::poll(&p, 1, 1000), 1);
    const long n = ::recv(tx, back.data(), back.size(), 0);
    ASSERT_EQ(n, 256);
    back.resize(256);
    EXPECT_EQ(back, ec);

    // Nothing more: a bounded wait.
    auto r = src.Read(chunk, 10);
    ASSERT_TRUE(r.ok());
    EXPECT_EQ(*r, ReadOutcome::kTimeout);
    ::close(tx);
}

TEST(UdpSourceTest, OversizedDatagramIsFlaggedTruncated) {
    UdpConfig c = UdpLoopback();
    c.max_datagram_bytes = 64;
    UdpSource src(c);
    ASSERT_TRUE(src.Open().ok());
    const int tx = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    const sockaddr_in dst = Loopback(src.bound_port());
    std::vector<std::byte> d(100, std::byte{0x5A});
    ASSERT_EQ(
        ::sendto(tx, d.data(), d.size(), 0, reinterpret_cast<const sockaddr*>(&dst), sizeof(dst)),
        100);
    Chunk chunk;
    auto r = src.Read(chunk, 1000);
    ASSERT_TRUE(r.ok());
    ASSERT_EQ(*r, ReadOutcome::kData);
    EXPECT_TRUE(chunk.truncated);
    EXPECT_EQ(chunk.data.size(), 64u);
    EXPECT_EQ(src.truncated_datagrams(), 1);
    ::close(tx);
}

TEST(UdpSourceTest, BindConflictIsAnErrorValueAndNoReplyWithoutSender) {
    UdpSource a(UdpLoopback());
    ASSERT_TRUE(a.Open().ok());
    UdpConfig c = UdpLoopback();
    c.port = a.bound_port();
    UdpSource b(c);
    auto s = b.Open();
    ASSERT_FALSE(s.ok());
    EXPECT_NE(s.error().message.find("bind"), std::string::npos);
    EXPECT_EQ(b.state(), SourceState::kDisconnected);
    EXPECT_FALSE(a.Write(Bytes("EC"), 10).ok());
    EXPECT_TRUE(UdpEndpoint::Parse("10.0.0.7:4040").has_value());
    EXPECT_EQ(UdpEndpoint::Parse("10.0.0.7:4040")->ToString(), "10.0.0.7:4040");
    EXPECT_FALSE(UdpEndpoint::Parse("10.0.0.7").has_value());
    EXPECT_FALSE(UdpEndpoint::Parse("host:99999").has_value());
}

}  // namespace
}  // namespace pitmap::acq
