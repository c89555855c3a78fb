// SPDX-License-Identifier: MIT
// The real pitmap-acqd on a NovAtel ICOM channel (TCP client) against a loopback server that
// the test runs: the server accepts, checks that every configured LOG command arrives (one
// at a time, each answered "<OK\r\n[ICOM1]"), sends a real capture, then closes the
// connection and its listening socket. While it is down the daemon's connects are refused
// and it backs off; the server listens again on the same port, and the daemon must come back
// by itself and send every LOG command again. The log must hold every byte the server sent,
// the answers on RESPONSE_NOV with the command each answers, and the counters.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>

#include <variant>

#include "common/protocol/novatel/commands.hpp"
#include "pitmap/daemon_status_t.hpp"
#include "pitmap/receiver_response_t.hpp"
#include "tests/firmware_host/daemon/acqd_process_util.hpp"

namespace pitmap::acq {
namespace {

using testing::DecodeAs;

constexpr const char* kCapture = "oem7drv_ins1.gps";
const std::vector<std::string> kCommands = {
    "LOG ICOM1 INSPVAXB ONTIME 0.05", "LOG ICOM1 BESTPOSB ONTIME 1", "LOG ICOM1 TIMEB ONTIME 1"};
const std::string kAnswer = "<OK\r\n[ICOM1]";

// Listens on 127.0.0.1:`port` (0 = any); returns the fd or -1. Close-on-exec, so the daemon
// does not inherit it.
int Listen(int& port) {
    const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    const int one = 1;
    ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof(one));
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<std::uint16_t>(port));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof(a)) != 0 || ::listen(fd, 4) != 0) {
        ::close(fd);
        return -1;
    }
    socklen_t len = sizeof(a);
    ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len);
    port = ntohs(a.sin_port);
    return fd;
}

// Waits (bounded) for the daemon's connection.
int Accept(int listen_fd) {
    pollfd p{listen_fd, POLLIN, 0};
    if (::poll(&p, 1, 15'000) <= 0) return -1;
    return ::accept4(listen_fd, nullptr, nullptr, SOCK_CLOEXEC | SOCK_NONBLOCK);
}

std::string Encoded(const std::string& line) {
    const auto parsed = protocol::novatel::ParseCommand(line);
    std::string s = protocol::novatel::EncodeCommand(std::get<protocol::novatel::Command>(parsed));
    while (!s.empty() && (s.back() == '\r' || s.back() == '\n')) s.pop_back();
    return s;
}

std::string Config(const std::string& dir, int port) {
    std::string yaml = "lcm_url: \"memq://\"\nstatus_period_ms: 100\nlog:\n  directory: " + dir +
                       "/logs\n  prefix: tcp\n  min_free_bytes: 0\n  flush_interval_ms: 50\n"
                       "channels:\n  - id: nov\n    protocol: novatel\n    tcp: {host: 127.0.0.1, "
                       "port: " +
                       std::to_string(port) +
                       ", connect_timeout_ms: 500}\n"
                       "    setup_commands:\n";
    for (const auto& c : kCommands) yaml += "      - \"" + c + "\"\n";
    return yaml;
}

// One session of the server: accept, handshake, capture, wait until logged. The connection
// stays open (`conn`): the caller decides what goes away first.
void ServeSession(int listen_fd,
                  const std::vector<std::uint8_t>& capture,
                  std::vector<std::uint8_t>& written,
                  const std::string& log_dir,
                  int& conn) {
    conn = Accept(listen_fd);
    ASSERT_GE(conn, 0) << "the daemon did not connect";
    const auto lines = testing::AnswerCommands(conn, kCommands.size(), kAnswer, written);
    ASSERT_EQ(lines.size(), kCommands.size());
    for (std::size_t i = 0; i < kCommands.size(); ++i) EXPECT_EQ(lines[i], Encoded(kCommands[i]));
    ASSERT_TRUE(testing::WriteInOddChunks(conn, capture, written));
    EXPECT_TRUE(testing::WaitFor([&] {
        return testing::LoggedRawBytes(log_dir, "RAW_NOV") == written.size();
    })) << "logged "
        << testing::LoggedRawBytes(log_dir, "RAW_NOV") << " of " << written.size();
}

TEST(AcqdTcpRestartTest, ServerRestartOnTheSamePortReconnectsAndResendsEveryCommand) {
    const std::string dir = testing::FreshDir("acqd_tcp_restart");
    const auto capture =
        testing::ReadBytes(std::string(PITMAP_TEST_DATA_DIR) + "/novatel/" + kCapture);
    ASSERT_FALSE(capture.empty());
    int port = 0;
    int listen_fd = Listen(port);
    ASSERT_GE(listen_fd, 0);
    testing::WriteText(dir + "/c.yaml", Config(dir, port));
    const pid_t pid = testing::SpawnAcqd({"--config", dir + "/c.yaml"}, dir + "/err.txt");
    std::vector<std::uint8_t> written;

    int conn = -1;
    ServeSession(listen_fd, capture, written, dir + "/logs", conn);
    // The server goes away completely (listener first, so the daemon cannot sneak into its
    // backlog): connects are refused, the daemon backs off.
    ::close(listen_fd);
    ::close(conn);
    ASSERT_TRUE(testing::WaitFor([&] {
        const std::string err = testing::ReadText(dir + "/err.txt");
        return err.find("Connection refused") != std::string::npos;
    })) << testing::ReadText(dir + "/err.txt");
    std::this_thread::sleep_for(std::chrono::milliseconds(400));
    const int same_port = port;
    listen_fd = Listen(port);
    ASSERT_GE(listen_fd, 0) << "port " << same_port << " could not be bound again";
    ASSERT_EQ(port, same_port);
    ServeSession(listen_fd, capture, written, dir + "/logs", conn);

    // Stop while connected, so the count of reconnects and commands is exact.
    ::kill(pid, SIGTERM);
    ASSERT_EQ(testing::WaitExit(pid), 0) << testing::ReadText(dir + "/err.txt");
    ::close(conn);
    ::close(listen_fd);

    const auto events = testing::ReadLogDir(dir + "/logs");
    EXPECT_EQ(testing::RawBytesOf(events, "RAW_NOV"), written);
    EXPECT_EQ(written.size(), 2 * (capture.size() + kCommands.size() * kAnswer.size()));
    pitmap::channel_status_t last_channel;
    pitmap::daemon_status_t last_daemon;
    std::vector<pitmap::receiver_response_t> responses;
    for (const auto& e : events) {
        if (e.channel == "STATUS_NOV") last_channel = DecodeAs<pitmap::channel_status_t>(e.data);
        if (e.channel == "DAEMON_STATUS") last_daemon = DecodeAs<pitmap::daemon_status_t>(e.data);
        if (e.channel == "RESPONSE_NOV") {
            const auto r = DecodeAs<pitmap::receiver_response_t>(e.data);
            EXPECT_EQ(r.utime, e.timestamp);
            responses.push_back(r);
        }
        if (e.channel == "RAW_NOV") {
            const auto r = DecodeAs<pitmap::raw_bytes_t>(e.data);
            EXPECT_EQ(r.transport, pitmap::raw_bytes_t::TRANSPORT_TCP);
            EXPECT_EQ(r.peer, "127.0.0.1:" + std::to_string(port));
        }
    }
    ASSERT_EQ(responses.size(), 2 * kCommands.size());
    for (std::size_t i = 0; i < responses.size(); ++i) {
        EXPECT_EQ(responses[i].ok, 1);
        EXPECT_EQ(responses[i].text, "OK");
        EXPECT_EQ(responses[i].command, Encoded(kCommands[i % kCommands.size()]));
    }
    std::map<std::string, std::int64_t> expected;
    for (const auto& [kind, n] : testing::GoldenFrames(kCapture)) expected[kind] = 2 * n;
    const auto n_cmd = static_cast<std::int64_t>(2 * kCommands.size());
    expected["OK"] = n_cmd;
    expected["PROMPT"] = n_cmd;
    expected["CMD_SENT"] = n_cmd;  // each command once per connection: no retry was needed
    expected["CMD_OK"] = n_cmd;
    EXPECT_EQ(testing::FrameKinds(last_channel), expected);
    EXPECT_EQ(last_channel.bytes, static_cast<std::int64_t>(written.size()));
    EXPECT_EQ(last_channel.reconnects, 1);
    EXPECT_EQ(last_channel.crc_failures, 0);
    EXPECT_EQ(last_channel.transport, pitmap::raw_bytes_t::TRANSPORT_TCP);
    ASSERT_EQ(last_daemon.num_channels, 1);
    EXPECT_EQ(last_daemon.channels[0].reconnects, 1);
    EXPECT_EQ(last_daemon.log_events_dropped, 0);
}

}  // namespace
}  // namespace pitmap::acq
