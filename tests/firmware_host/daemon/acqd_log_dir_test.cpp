// SPDX-License-Identifier: MIT
// Issue 14 case 6 with the real pitmap-acqd: the log directory is deleted while 83P datagrams
// arrive on loopback UDP. The daemon must say so, count it in DAEMON_STATUS, create the
// directory again and go on logging there; a SIGHUP afterwards rotates normally (no endless
// "No such file or directory"). LCM is a file:// provider next to the log directory.
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>

#include <arpa/inet.h>

#include <filesystem>

#include "common/protocol/deltat/record83p.hpp"
#include "pitmap/daemon_status_t.hpp"
#include "tests/firmware_host/daemon/acqd_process_util.hpp"

namespace pitmap::acq {
namespace {

using testing::DecodeAs;

// Sequence numbers of the RAW_MB events in the *.lcmlog files of `dir` (none if it is gone).
std::vector<std::int64_t> RawSeqs(const std::string& dir) {
    std::vector<std::int64_t> out;
    std::error_code ec;
    if (!std::filesystem::is_directory(dir, ec)) return out;
    for (const auto& e : testing::ReadLogDir(dir)) {
        if (e.channel == "RAW_MB") out.push_back(DecodeAs<pitmap::raw_bytes_t>(e.data).seq);
    }
    return out;
}

class Pinger {
public:
    explicit Pinger(int port) : fd_(::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0)) {
        to_.sin_family = AF_INET;
        to_.sin_port = htons(static_cast<std::uint16_t>(port));
        to_.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    }
    ~Pinger() { ::close(fd_); }
    void Send() {
        const auto p = testing::TestPing83P(n_++);
        ::sendto(fd_, p.data(), p.size(), 0, reinterpret_cast<const sockaddr*>(&to_), sizeof(to_));
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }

private:
    int fd_;
    sockaddr_in to_{};
    std::uint32_t n_ = 0;
};

TEST(AcqdLogDirTest, DeletedLogDirectoryIsReportedRecreatedAndLoggingGoesOn) {
    const std::string dir = testing::FreshDir("acqd_log_dir_deleted");
    const std::string logs = dir + "/logs";
    const std::string published = dir + "/published.lcmlog";
    const std::string err = dir + "/err.txt";
    const int port = testing::FreeUdpPort();
    testing::WriteText(dir + "/c.yaml",
                       "lcm_url: \"file://" + published +
                           "?mode=w\"\nstatus_period_ms: 100\nlog:\n  directory: " + logs +
                           "\n  prefix: t\n  min_free_bytes: 0\n  flush_interval_ms: 50\n"
                           "channels:\n  - id: mb\n    protocol: deltat_83p\n"
                           "    udp: {bind_address: 127.0.0.1, allowed_senders: [127.0.0.1],"
                           " port: " +
                           std::to_string(port) + "}\n");
    const pid_t pid = testing::SpawnAcqd({"--config", dir + "/c.yaml"}, err);
    ASSERT_TRUE(testing::WaitFor([&] {
        return testing::ReadText(err).find("running") != std::string::npos;
    })) << testing::ReadText(err);
    Pinger pinger(port);
    ASSERT_TRUE(testing::WaitFor([&] {
        pinger.Send();
        return RawSeqs(logs).size() >= 10;
    }));
    std::filesystem::remove_all(logs);
    // Datagrams keep coming: the daemon notices, says so and logs into a new directory.
    ASSERT_TRUE(testing::WaitFor([&] {
        pinger.Send();
        return testing::ReadText(err).find("was deleted while open") != std::string::npos &&
               RawSeqs(logs).size() >= 10;
    })) << testing::ReadText(err);
    ::kill(pid, SIGHUP);
    ASSERT_TRUE(testing::WaitFor([&] {
        pinger.Send();
        return testing::ReadText(err).find("rotating") != std::string::npos;
    }));
    for (int i = 0; i < 20; ++i) pinger.Send();
    ::kill(pid, SIGTERM);
    ASSERT_EQ(testing::WaitExit(pid), 0) << testing::ReadText(err);

    const std::string text = testing::ReadText(err);
    // ("created it again" too, unless the daemon's next file won the race with the rmdir of
    // remove_all: then that file kept the directory; the log writer test covers the message.)
    EXPECT_EQ(text.find("No such file or directory"), std::string::npos) << text;
    // The new directory holds a run of consecutive datagrams, in at least two files (SIGHUP).
    const auto seqs = RawSeqs(logs);
    ASSERT_GE(seqs.size(), 10u);
    for (std::size_t i = 1; i < seqs.size(); ++i) EXPECT_EQ(seqs[i], seqs[i - 1] + 1) << i;
    int files = 0;
    for (const auto& e : std::filesystem::directory_iterator(logs)) {
        files += e.path().extension() == ".lcmlog";
    }
    EXPECT_GE(files, 2);
    // DAEMON_STATUS says what happened.
    pitmap::daemon_status_t last;
    {
        lcm::LogFile log(published, "r");
        ASSERT_TRUE(log.good());
        while (const lcm::LogEvent* ev = log.readNextEvent()) {
            if (std::string(ev->channel) != "DAEMON_STATUS") continue;
            const auto* p = static_cast<const std::uint8_t*>(ev->data);
            last = DecodeAs<pitmap::daemon_status_t>(std::vector<std::uint8_t>(p, p + ev->datalen));
        }
    }
    EXPECT_EQ(last.log_dir_lost, 1);
    EXPECT_GE(last.log_events_lost, 10);
    EXPECT_EQ(last.log_directory, logs);
    EXPECT_EQ(last.logging, pitmap::daemon_status_t::LOGGING_ON);
}

}  // namespace
}  // namespace pitmap::acq
