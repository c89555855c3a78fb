// SPDX-License-Identifier: MIT
// A full disk for real: the daemon logs onto a small tmpfs (mounted in a private mount
// namespace of this test process, so nothing shows outside it) while 83P datagrams arrive
// on loopback UDP. The free-space guard must stop logging cleanly (DAEMON_STATUS says
// LOGGING_DISK_GUARD, no write error), the daemon must keep publishing: its LCM side is a
// file:// provider on the ordinary disk, so every datagram can be checked there, and the
// log on the tmpfs must read back exactly up to where it stopped.
// Without the guard (issue 14 case 4) the writes fail with ENOSPC and every retry opens a new
// segment: none of them may be left behind empty.
// Needs root (unshare(CLONE_NEWNS) + mount); skips with a message where that is refused.
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sched.h>
#include <sys/mount.h>
#include <sys/socket.h>

#include <arpa/inet.h>

#include <cstring>
#include <filesystem>
#include <regex>

#include "common/protocol/deltat/record83p.hpp"
#include "pitmap/daemon_status_t.hpp"
#include "pitmap/multibeam_ping_t.hpp"
#include "tests/firmware_host/daemon/acqd_process_util.hpp"

namespace pitmap::acq {
namespace {

using testing::DecodeAs;

constexpr std::int64_t kTmpfsBytes = 2 << 20;
constexpr std::int64_t kMinFreeBytes = 1 << 20;

// RAW_MB payloads of the complete events of an LCM log file.
std::vector<std::vector<std::uint8_t>> RawDatagrams(const std::vector<testing::LogEvent>& events) {
    std::vector<std::vector<std::uint8_t>> out;
    for (const auto& e : events) {
        if (e.channel == "RAW_MB") out.push_back(DecodeAs<pitmap::raw_bytes_t>(e.data).data);
    }
    return out;
}

std::vector<testing::LogEvent> ReadLogFile(const std::string& path) {
    std::vector<testing::LogEvent> out;
    lcm::LogFile log(path, "r");
    if (!log.good()) return out;
    while (const lcm::LogEvent* ev = log.readNextEvent()) {
        const auto* p = static_cast<const std::uint8_t*>(ev->data);
        out.push_back({ev->channel, ev->timestamp, std::vector<std::uint8_t>(p, p + ev->datalen)});
    }
    return out;
}

class AcqdTmpfsFullTest : public ::testing::Test {
protected:
    void SetUp() override {
        // One directory per test: ctest runs them in parallel.
        dir_ = testing::FreshDir(std::string("acqd_tmpfs_full_") +
                                 ::testing::UnitTest::GetInstance()->current_test_info()->name());
        logs_ = dir_ + "/logs";
        std::filesystem::create_directories(logs_);
        if (::geteuid() != 0) GTEST_SKIP() << "needs root for unshare(CLONE_NEWNS) and mount";
        if (::unshare(CLONE_NEWNS) != 0) {
            GTEST_SKIP() << "unshare(CLONE_NEWNS) refused: " << std::strerror(errno);
        }
        // Private propagation: the tmpfs stays inside this process's namespace.
        if (::mount(nullptr, "/", nullptr, MS_REC | MS_PRIVATE, nullptr) != 0) {
            GTEST_SKIP() << "cannot make mounts private: " << std::strerror(errno);
        }
        const std::string opts = "size=" + std::to_string(kTmpfsBytes) + ",mode=0755";
        if (::mount("tmpfs", logs_.c_str(), "tmpfs", MS_NOSUID | MS_NODEV, opts.c_str()) != 0) {
            GTEST_SKIP() << "mount -t tmpfs refused: " << std::strerror(errno);
        }
        mounted_ = true;
    }
    void TearDown() override {
        if (mounted_) ::umount2(logs_.c_str(), MNT_DETACH);
    }
    std::string dir_;
    std::string logs_;
    bool mounted_ = false;
};

TEST_F(AcqdTmpfsFullTest, DiskGuardStopsLoggingCleanlyWhilePublishingGoesOn) {
    const int port = testing::FreeUdpPort();
    const std::string published = dir_ + "/published.lcmlog";
    testing::WriteText(
        dir_ + "/c.yaml",
        "lcm_url: \"file://" + published +
            "?mode=w\"\nstatus_period_ms: 100\nlog:\n"
            "  directory: " +
            logs_ + "\n  prefix: full\n  min_free_bytes: " + std::to_string(kMinFreeBytes) +
            "\n  disk_check_interval_ms: 20\n"
            "  flush_interval_ms: 50\nchannels:\n  - id: mb\n    protocol: deltat_83p\n"
            "    udp: {bind_address: 127.0.0.1, allowed_senders: [127.0.0.1], port: " +
            std::to_string(port) + "}\n");
    const pid_t pid = testing::SpawnAcqd({"--config", dir_ + "/c.yaml"}, dir_ + "/err.txt");
    ASSERT_TRUE(testing::WaitFor([&] {
        return testing::ReadText(dir_ + "/err.txt").find("running") != std::string::npos;
    })) << testing::ReadText(dir_ + "/err.txt");

    const int fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    sockaddr_in to{};
    to.sin_family = AF_INET;
    to.sin_port = htons(static_cast<std::uint16_t>(port));
    to.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    std::vector<std::vector<std::uint8_t>> sent;
    auto send_one = [&] {
        sent.push_back(testing::TestPing83P(static_cast<std::uint32_t>(sent.size()), true));
        ::sendto(fd,
                 sent.back().data(),
                 sent.back().size(),
                 0,
                 reinterpret_cast<const sockaddr*>(&to),
                 sizeof(to));
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
    };
    // Fill the tmpfs until the daemon says logging stopped (bounded: 1 MiB needs ~150 pings).
    bool stopped = false;
    while (!stopped && sent.size() < 3000) {
        send_one();
        if (sent.size() % 10 == 0) {
            stopped =
                testing::ReadText(dir_ + "/err.txt").find("logging stopped") != std::string::npos;
        }
    }
    ASSERT_TRUE(stopped) << testing::ReadText(dir_ + "/err.txt");
    const std::size_t at_guard = sent.size();
    // Publishing goes on: more datagrams, until the LCM side (file://, stdio-buffered) shows
    // the last of them. Fillers push the buffer out; they are checked like the others.
    for (int i = 0; i < 50; ++i) send_one();
    const std::size_t must_publish = sent.size();
    ASSERT_TRUE(testing::WaitFor([&] {
        if (RawDatagrams(ReadLogFile(published)).size() >= must_publish) return true;
        send_one();
        return false;
    }));
    ::close(fd);
    ::kill(pid, SIGTERM);
    ASSERT_EQ(testing::WaitExit(pid), 0) << testing::ReadText(dir_ + "/err.txt");

    // LCM side: every datagram, in order, each decoded; the last status reports the guard.
    const auto pub_events = ReadLogFile(published);
    const auto pub_raw = RawDatagrams(pub_events);
    ASSERT_GE(pub_raw.size(), must_publish);
    ASSERT_LE(pub_raw.size(), sent.size());
    for (std::size_t i = 0; i < pub_raw.size(); ++i) ASSERT_EQ(pub_raw[i], sent[i]) << i;
    std::size_t pings = 0;
    pitmap::daemon_status_t last;
    for (const auto& e : pub_events) {
        if (e.channel == "MULTIBEAM_PING_MB") {
            EXPECT_EQ(DecodeAs<pitmap::multibeam_ping_t>(e.data).ping_number,
                      static_cast<std::int64_t>(pings));
            ++pings;
        }
        if (e.channel == "DAEMON_STATUS") last = DecodeAs<pitmap::daemon_status_t>(e.data);
    }
    EXPECT_EQ(pings, pub_raw.size());
    EXPECT_EQ(last.logging, pitmap::daemon_status_t::LOGGING_DISK_GUARD);
    EXPECT_GT(last.log_events_dropped, 0);
    EXPECT_GE(last.disk_free_bytes, 0);
    EXPECT_LT(last.disk_free_bytes, kMinFreeBytes);
    ASSERT_EQ(last.num_channels, 1);
    EXPECT_EQ(last.channels[0].frames, static_cast<std::int64_t>(pub_raw.size()));

    // Log side: stopped before the datagrams that came after the guard, nothing torn: every
    // event the writer counted reads back, the files hold exactly those bytes, and the raw
    // datagrams are the first ones sent, byte for byte.
    const auto log_events = testing::ReadLogDir(logs_);
    const auto log_raw = RawDatagrams(log_events);
    ASSERT_FALSE(log_raw.empty());
    EXPECT_LT(log_raw.size(), at_guard);
    for (std::size_t i = 0; i < log_raw.size(); ++i) ASSERT_EQ(log_raw[i], sent[i]) << i;
    EXPECT_EQ(static_cast<std::int64_t>(log_events.size()), last.log_events_written);
    std::int64_t file_bytes = 0;
    for (const auto& e : std::filesystem::directory_iterator(logs_)) {
        if (e.path().extension() == ".lcmlog") {
            file_bytes += static_cast<std::int64_t>(std::filesystem::file_size(e.path()));
        }
    }
    EXPECT_EQ(file_bytes, last.log_bytes_written);
    EXPECT_LT(file_bytes, kTmpfsBytes - kMinFreeBytes / 2);
    EXPECT_EQ(testing::ReadText(dir_ + "/err.txt").find("No space left"), std::string::npos);
}

TEST_F(AcqdTmpfsFullTest, RetriesOnAFullDiskLeaveNoEmptySegment) {
    const int port = testing::FreeUdpPort();
    testing::WriteText(dir_ + "/c.yaml",
                       "lcm_url: \"memq://\"\nstatus_period_ms: 100\nlog:\n  directory: " + logs_ +
                           "\n  prefix: full\n  min_free_bytes: 0\n  error_retry_ms: 20\n"
                           "  flush_interval_ms: 50\nchannels:\n  - id: mb\n"
                           "    protocol: deltat_83p\n"
                           "    udp: {bind_address: 127.0.0.1, allowed_senders: [127.0.0.1],"
                           " port: " +
                           std::to_string(port) + "}\n");
    const pid_t pid = testing::SpawnAcqd({"--config", dir_ + "/c.yaml"}, dir_ + "/err.txt");
    ASSERT_TRUE(testing::WaitFor([&] {
        return testing::ReadText(dir_ + "/err.txt").find("running") != std::string::npos;
    })) << testing::ReadText(dir_ + "/err.txt");
    const int fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    sockaddr_in to{};
    to.sin_family = AF_INET;
    to.sin_port = htons(static_cast<std::uint16_t>(port));
    to.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    // Fill the tmpfs, then go on until a retry (a later segment, -001 or beyond) failed too.
    const std::regex retried("-0[0-9][1-9]\\.lcmlog: No space left");
    bool retried_seen = false;
    for (std::uint32_t n = 0; n < 20'000 && !retried_seen; ++n) {
        const auto ping = testing::TestPing83P(n, true);
        ::sendto(
            fd, ping.data(), ping.size(), 0, reinterpret_cast<const sockaddr*>(&to), sizeof(to));
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
        if (n % 20 == 0) {
            retried_seen = std::regex_search(testing::ReadText(dir_ + "/err.txt"), retried);
        }
    }
    ::close(fd);
    ::kill(pid, SIGTERM);
    ASSERT_EQ(testing::WaitExit(pid), 0) << testing::ReadText(dir_ + "/err.txt");
    ASSERT_TRUE(retried_seen) << testing::ReadText(dir_ + "/err.txt");
    int files = 0;
    for (const auto& e : std::filesystem::directory_iterator(logs_)) {
        if (e.path().extension() != ".lcmlog") continue;
        ++files;
        EXPECT_GT(std::filesystem::file_size(e.path()), 0u) << e.path() << " left empty";
        EXPECT_FALSE(ReadLogFile(e.path().string()).empty()) << e.path();
    }
    EXPECT_GE(files, 1);
}

}  // namespace
}  // namespace pitmap::acq
