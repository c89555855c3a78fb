// SPDX-License-Identifier: MIT
// The real pitmap-acqd on a serial channel whose device is a pseudo-terminal behind a stable
// symlink (as /dev/serial/by-id/... is for a USB adapter). The test plays the receiver on the
// master side: it answers every LOG command with "<OK\r\n[COM1]", writes a real NovAtel
// capture in odd-sized chunks, then unplugs the "adapter" (closes the master, removes the
// pty and the link), plugs a new pty in behind the same link, answers the re-sent commands
// and writes the capture again. After SIGTERM the log must hold every byte written, in order,
// and the per-kind frame counts of the golden file (twice), and count exactly one reconnect
// in the last STATUS_NOV and DAEMON_STATUS.
#include <gtest/gtest.h>
#include <pty.h>
#include <termios.h>

#include <filesystem>
#include <variant>

#include "common/protocol/novatel/commands.hpp"
#include "pitmap/daemon_status_t.hpp"
#include "pitmap/receiver_response_t.hpp"
#include "tests/firmware_host/daemon/acqd_process_util.hpp"

namespace pitmap::acq {
namespace {

using testing::DecodeAs;

constexpr const char* kCapture = "oem7drv_ins2.gps";
const std::vector<std::string> kCommands = {
    "LOG INSPVASB ONTIME 0.02", "LOG RAWIMUSXB ONNEW", "LOG TIMEB ONTIME 1"};
const std::string kAnswer = "<OK\r\n[COM1]";

// A pty pair in raw mode (no echo, no line discipline) from the start, so nothing the test
// writes before the daemon configures the slave is echoed or mangled. The test keeps the
// slave open too: a master whose slave has no opener reads EIO/POLLHUP.
struct Pty {
    int master = -1;
    int slave = -1;
    std::string slave_path;

    bool Open() {
        termios tio{};
        ::cfmakeraw(&tio);
        tio.c_cflag |= CLOCAL | CREAD;
        char name[128] = {};
        if (::openpty(&master, &slave, name, &tio, nullptr) != 0) return false;
        slave_path = name;
        ::fcntl(master, F_SETFL, ::fcntl(master, F_GETFL) | O_NONBLOCK);
        // Not inherited by the daemon: a copy of the master there would keep the pty alive.
        ::fcntl(master, F_SETFD, FD_CLOEXEC);
        ::fcntl(slave, F_SETFD, FD_CLOEXEC);
        return true;
    }
    // The "unplug": the daemon's reads on the slave hang up, the /dev/pts node goes away.
    void Close() {
        if (master >= 0) ::close(master);
        if (slave >= 0) ::close(slave);
        master = slave = -1;
    }
};

// Points `link` at `target` atomically (a new link renamed over the old one).
void Relink(const std::string& target, const std::string& link) {
    const std::string tmp = link + ".new";
    std::filesystem::remove(tmp);
    std::filesystem::create_symlink(target, tmp);
    std::filesystem::rename(tmp, link);
}

std::string Encoded(const std::string& line) {
    const auto parsed = protocol::novatel::ParseCommand(line);
    std::string s = protocol::novatel::EncodeCommand(std::get<protocol::novatel::Command>(parsed));
    while (!s.empty() && (s.back() == '\r' || s.back() == '\n')) s.pop_back();
    return s;
}

std::string Config(const std::string& dir, const std::string& link) {
    std::string yaml = "lcm_url: \"memq://\"\nstatus_period_ms: 100\nlog:\n  directory: " + dir +
                       "/logs\n  prefix: pty\n  min_free_bytes: 0\n  flush_interval_ms: 50\n"
                       "channels:\n  - id: nov\n    protocol: novatel\n    serial: {path: " +
                       link + ", baud: 460800}\n    imu_rate_hz: 100\n    setup_commands:\n";
    for (const auto& c : kCommands) yaml += "      - \"" + c + "\"\n";
    return yaml;
}

// Handshake then the capture; waits until the daemon logged everything written so far.
void PlayReceiver(const Pty& pty,
                  const std::vector<std::uint8_t>& capture,
                  std::vector<std::uint8_t>& written,
                  const std::string& log_dir) {
    const auto lines = testing::AnswerCommands(pty.master, kCommands.size(), kAnswer, written);
    ASSERT_EQ(lines.size(), kCommands.size());
    for (std::size_t i = 0; i < kCommands.size(); ++i) EXPECT_EQ(lines[i], Encoded(kCommands[i]));
    ASSERT_TRUE(testing::WriteInOddChunks(pty.master, capture, written));
    ASSERT_TRUE(testing::WaitFor([&] {
        return testing::LoggedRawBytes(log_dir, "RAW_NOV") == written.size();
    })) << "logged "
        << testing::LoggedRawBytes(log_dir, "RAW_NOV") << " of " << written.size();
}

TEST(AcqdSerialPtyTest, CaptureThroughPtyWithUnplugAndReplugIsLoggedExactly) {
    const std::string dir = testing::FreshDir("acqd_pty");
    const std::string link = dir + "/novatel-by-id";
    const auto capture =
        testing::ReadBytes(std::string(PITMAP_TEST_DATA_DIR) + "/novatel/" + kCapture);
    ASSERT_FALSE(capture.empty());

    Pty pty;
    ASSERT_TRUE(pty.Open());
    Relink(pty.slave_path, link);
    testing::WriteText(dir + "/c.yaml", Config(dir, link));
    const pid_t pid = testing::SpawnAcqd({"--config", dir + "/c.yaml"}, dir + "/err.txt");
    std::vector<std::uint8_t> written;

    PlayReceiver(pty, capture, written, dir + "/logs");
    const std::size_t before_unplug = written.size();

    // Unplug: the device node and the link disappear while the daemon retries with backoff.
    pty.Close();
    std::filesystem::remove(link);
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    // Replug: a new pty (often the same /dev/pts number) behind the same link.
    Pty pty2;
    ASSERT_TRUE(pty2.Open());
    Relink(pty2.slave_path, link);
    PlayReceiver(pty2, capture, written, dir + "/logs");

    ::kill(pid, SIGTERM);
    ASSERT_EQ(testing::WaitExit(pid), 0) << testing::ReadText(dir + "/err.txt");
    pty2.Close();

    const auto events = testing::ReadLogDir(dir + "/logs");
    // Every byte written into the master, in order: the answers and both capture passes.
    EXPECT_EQ(testing::RawBytesOf(events, "RAW_NOV"), written);
    EXPECT_EQ(written.size(), 2 * (capture.size() + kCommands.size() * kAnswer.size()));
    EXPECT_GT(before_unplug, 0u);

    pitmap::channel_status_t last_channel;
    pitmap::daemon_status_t last_daemon;
    std::vector<pitmap::receiver_response_t> responses;
    for (const auto& e : events) {
        if (e.channel == "STATUS_NOV") last_channel = DecodeAs<pitmap::channel_status_t>(e.data);
        if (e.channel == "DAEMON_STATUS") last_daemon = DecodeAs<pitmap::daemon_status_t>(e.data);
        if (e.channel == "RESPONSE_NOV") {
            responses.push_back(DecodeAs<pitmap::receiver_response_t>(e.data));
        }
    }
    // Per-kind counts: the golden file twice, plus one OK and one port prompt per answer.
    std::map<std::string, std::int64_t> expected;
    for (const auto& [kind, n] : testing::GoldenFrames(kCapture)) expected[kind] = 2 * n;
    expected["OK"] = static_cast<std::int64_t>(2 * kCommands.size());
    expected["PROMPT"] = static_cast<std::int64_t>(2 * kCommands.size());
    // The status also carries the command counters as pseudo kinds: each sent once, accepted.
    expected["CMD_SENT"] = static_cast<std::int64_t>(2 * kCommands.size());
    expected["CMD_OK"] = static_cast<std::int64_t>(2 * kCommands.size());
    EXPECT_EQ(testing::FrameKinds(last_channel), expected);
    EXPECT_EQ(last_channel.bytes, static_cast<std::int64_t>(written.size()));
    EXPECT_EQ(last_channel.crc_failures, 0);
    EXPECT_EQ(last_channel.queue_drops, 0);
    EXPECT_EQ(last_channel.reconnects, 1);
    EXPECT_EQ(last_channel.transport, pitmap::raw_bytes_t::TRANSPORT_SERIAL);
    ASSERT_EQ(last_daemon.num_channels, 1);
    EXPECT_EQ(last_daemon.channels[0].reconnects, 1);
    EXPECT_EQ(last_daemon.log_events_dropped, 0);
    // Both handshakes are in the log with the command each answer belongs to.
    ASSERT_EQ(responses.size(), 2 * kCommands.size());
    for (std::size_t i = 0; i < responses.size(); ++i) {
        EXPECT_EQ(responses[i].ok, 1);
        EXPECT_EQ(responses[i].command, Encoded(kCommands[i % kCommands.size()]));
    }
}

}  // namespace
}  // namespace pitmap::acq
