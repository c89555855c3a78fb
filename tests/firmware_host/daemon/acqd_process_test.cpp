// SPDX-License-Identifier: MIT
// The real pitmap-acqd binary: invalid configs (every problem listed, non-zero exit),
// a capture replayed from a file source and SIGTERM (log byte-exact, status published),
// 83P datagrams over loopback UDP, kill -9 mid-run then reading the log, and a full disk
// (RLIMIT_FSIZE) that stops logging without stopping the daemon.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <arpa/inet.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>

#include "common/protocol/deltat/record83p.hpp"
#include "common/vehicle.hpp"
#include "pitmap/daemon_status_t.hpp"
#include "pitmap/multibeam_ping_t.hpp"
#include "pitmap/raw_bytes_t.hpp"
#include "tests/firmware_host/daemon/acq_test_util.hpp"

namespace pitmap::acq {
namespace {

using testing::DecodeAs;

const std::string kBin = std::string(PITMAP_BIN_DIR) + "/pitmap-acqd";

struct Child {
    pid_t pid = -1;
    std::string err_path;
};

// Starts pitmap-acqd with `args`, stderr to a file; `fsize_limit` > 0 sets RLIMIT_FSIZE.
Child Spawn(const std::vector<std::string>& args,
            const std::string& err_path,
            rlim_t fsize_limit = 0) {
    Child c;
    c.err_path = err_path;
    c.pid = fork();
    if (c.pid == 0) {
        const int fd = open(err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        dup2(fd, 2);
        dup2(fd, 1);
        if (fsize_limit > 0) {
            rlimit rl{fsize_limit, fsize_limit};
            setrlimit(RLIMIT_FSIZE, &rl);
            signal(SIGXFSZ, SIG_IGN);
        }
        std::vector<char*> argv;
        argv.push_back(const_cast<char*>(kBin.c_str()));
        for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
        argv.push_back(nullptr);
        execv(kBin.c_str(), argv.data());
        _exit(127);
    }
    return c;
}

int Wait(pid_t pid) {
    int status = 0;
    waitpid(pid, &status, 0);
    if (WIFEXITED(status)) return WEXITSTATUS(status);
    return 128 + WTERMSIG(status);
}

std::string ReadText(const std::string& path) {
    std::ifstream in(path);
    return std::string(std::istreambuf_iterator<char>(in), {});
}

void WriteText(const std::string& path, const std::string& text) {
    std::ofstream out(path);
    out << text;
}

// Waits (bounded, not timed: the test's outcome does not depend on the duration) until
// `pred` holds.
template <typename P>
bool WaitFor(P pred, int max_ms = 10'000) {
    for (int i = 0; i < max_ms / 10; ++i) {
        if (pred()) return true;
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return pred();
}

TEST(AcqdProcessTest, InvalidConfigListsEveryProblem) {
    const std::string dir = testing::FreshDir("acqd_invalid");
    WriteText(dir + "/bad.yaml", R"(lcm_url: "memq://"
status_period_ms: 5
logg: {}
channels:
  - id: "nov 1"
    protocol: novatel
    serial: {path: /dev/null, baud: 12345}
    setup_commands: ["FROB THE RECEIVER"]
    colour: red
  - id: sonar
    protocol: sidescan
    udp: {port: 70000}
    tcp: {host: 127.0.0.1, port: 3001}
)");
    const Child c = Spawn({"--config", dir + "/bad.yaml", "--check-config"}, dir + "/err.txt");
    EXPECT_EQ(Wait(c.pid), 2);
    const std::string err = ReadText(c.err_path);
    for (const char* expected : {"status_period_ms",
                                 "logg",
                                 "log: required",
                                 "channels[0]: id 'nov 1'",
                                 "baud",
                                 "FROB THE RECEIVER",
                                 "colour",
                                 "sidescan",
                                 "channels[1]: needs exactly one",
                                 "port"}) {
        EXPECT_NE(err.find(expected), std::string::npos) << "missing: " << expected << "\n" << err;
    }
    // Not a config at all, and a missing file.
    WriteText(dir + "/list.yaml", "- a\n- b\n");
    EXPECT_EQ(Wait(Spawn({"--config", dir + "/list.yaml", "--check-config"}, dir + "/e2").pid), 2);
    EXPECT_EQ(Wait(Spawn({"--config", dir + "/none.yaml"}, dir + "/e3").pid), 2);
    EXPECT_NE(ReadText(dir + "/e3").find("none.yaml"), std::string::npos);
    EXPECT_EQ(Wait(Spawn({"--bogus"}, dir + "/e4").pid), 2);
}

TEST(AcqdProcessTest, ShippedConfigsAreValid) {
    for (const char* name : {"roaz.yaml", "test-loopback.yaml"}) {
        const std::string dir = testing::FreshDir("acqd_shipped");
        const Child c = Spawn({"--config",
                               std::string(PITMAP_SOURCE_DIR) + "/firmware_host/config/" + name,
                               "--check-config"},
                              dir + "/err.txt");
        EXPECT_EQ(Wait(c.pid), 0) << ReadText(dir + "/err.txt");
    }
}

std::string FileReplayConfig(const std::string& dir, const std::string& capture) {
    return "lcm_url: \"memq://\"\nstatus_period_ms: 100\nlog:\n  directory: " + dir +
           "/logs\n  prefix: t\n  min_free_bytes: 0\n  flush_interval_ms: 50\n"
           "channels:\n  - id: nov\n    protocol: novatel\n    file: {path: " +
           capture +
           ", chunk_bytes: 333}\n    imu_rate_hz: 100\n"
           "vehicle:\n  pitmap_vehicle: 1\n  name: TEST\n  sonar:\n    lever_arm_m: [1.0, 0.0, "
           "0.5]\n    mount: {orientation: down, connector: port}\n";
}

TEST(AcqdProcessTest, FileReplayLogsEveryByteAndExitsAtTheEnd) {
    const std::string dir = testing::FreshDir("acqd_replay");
    const std::string capture = std::string(PITMAP_TEST_DATA_DIR) + "/novatel/oem7drv_ins2.gps";
    WriteText(dir + "/c.yaml", FileReplayConfig(dir, capture));
    const Child c = Spawn({"--config", dir + "/c.yaml"}, dir + "/err.txt");
    EXPECT_EQ(Wait(c.pid), 0) << ReadText(c.err_path);
    const auto events = testing::ReadLogDir(dir + "/logs");
    std::vector<std::uint8_t> raw;
    std::map<std::string, int> n;
    pitmap::daemon_status_t last_status;
    for (const auto& e : events) {
        ++n[e.channel];
        if (e.channel == "RAW_NOV") {
            const auto r = DecodeAs<pitmap::raw_bytes_t>(e.data);
            EXPECT_EQ(r.transport, pitmap::raw_bytes_t::TRANSPORT_FILE);
            raw.insert(raw.end(), r.data.begin(), r.data.end());
        }
        if (e.channel == "DAEMON_STATUS") last_status = DecodeAs<pitmap::daemon_status_t>(e.data);
    }
    EXPECT_EQ(raw, testing::ReadBytes(capture));
    EXPECT_EQ(n["IMU_NOV"], 766);
    EXPECT_EQ(n["INS_PVA_NOV"], 68);
    EXPECT_GE(n["STATUS_NOV"], 1);
    EXPECT_GE(n["CLOCK_SYNC"], 2);
    ASSERT_GE(n["DAEMON_STATUS"], 1);
    ASSERT_EQ(last_status.num_channels, 1);
    EXPECT_EQ(last_status.channels[0].name, "nov");
    EXPECT_EQ(last_status.channels[0].bytes, 65748);
    EXPECT_EQ(last_status.channels[0].frames, 835);
    EXPECT_EQ(last_status.channels[0].crc_failures, 0);
    // The copied section is a vehicle file the processor reads (common/vehicle.hpp).
    const auto vehicle = pitmap::ReadVehicleFile(dir + "/logs/vehicle.yaml");
    ASSERT_TRUE(vehicle) << vehicle.error().message;
    EXPECT_EQ(vehicle->name, "TEST");
    EXPECT_EQ(vehicle->sonar_lever_arm_m, Eigen::Vector3d(1.0, 0.0, 0.5));
    EXPECT_EQ(vehicle->connector, pitmap::ConnectorDirection::kPort);
}

std::string UdpConfig(const std::string& dir, int port) {
    return "lcm_url: \"memq://\"\nlog:\n  directory: " + dir +
           "/logs\n  prefix: t\n  min_free_bytes: 0\n  flush_interval_ms: 50\n"
           "channels:\n  - id: mb\n    protocol: deltat_83p\n    udp: {bind_address: 127.0.0.1, "
           "allowed_senders: [127.0.0.1], port: " +
           std::to_string(port) + "}\n";
}

// Sends pings until the daemon's log holds at least `until` RAW events (bounded).
int SendPings(int port,
              const std::string& log_dir,
              int until,
              std::vector<std::vector<std::uint8_t>>& sent) {
    const int fd = socket(AF_INET, SOCK_DGRAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<std::uint16_t>(port));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    for (int i = 0; i < 2000; ++i) {
        sent.push_back(testing::TestPing83P(static_cast<std::uint32_t>(i)));
        sendto(fd,
               sent.back().data(),
               sent.back().size(),
               0,
               reinterpret_cast<sockaddr*>(&a),
               sizeof(a));
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
        if (i % 20 == 19) {
            int raws = 0;
            for (const auto& e : testing::ReadLogDir(log_dir)) raws += e.channel == "RAW_MB";
            if (raws >= until) break;
        }
    }
    close(fd);
    return static_cast<int>(sent.size());
}

TEST(AcqdProcessTest, UdpPingsThenKillDashNineLeavesAReadableLog) {
    const std::string dir = testing::FreshDir("acqd_kill9");
    const int port = testing::FreeUdpPort();
    WriteText(dir + "/c.yaml", UdpConfig(dir, port));
    const Child c = Spawn({"--config", dir + "/c.yaml"}, dir + "/err.txt");
    ASSERT_TRUE(WaitFor([&] { return ReadText(c.err_path).find("running") != std::string::npos; }));
    std::vector<std::vector<std::uint8_t>> sent;
    SendPings(port, dir + "/logs", 40, sent);
    kill(c.pid, SIGKILL);
    EXPECT_EQ(Wait(c.pid), 128 + SIGKILL);
    // Everything up to the last complete event reads back; raw datagrams are what was sent,
    // in order, and each ping decodes.
    const auto events = testing::ReadLogDir(dir + "/logs");
    std::size_t raw_index = 0;
    int pings = 0;
    for (const auto& e : events) {
        if (e.channel == "RAW_MB") {
            const auto r = DecodeAs<pitmap::raw_bytes_t>(e.data);
            ASSERT_LT(raw_index, sent.size());
            EXPECT_EQ(r.data, sent[raw_index]) << raw_index;
            EXPECT_EQ(r.seq, static_cast<std::int64_t>(raw_index));
            EXPECT_EQ(r.transport, pitmap::raw_bytes_t::TRANSPORT_UDP);
            ++raw_index;
        } else if (e.channel == "MULTIBEAM_PING_MB") {
            const auto p = DecodeAs<pitmap::multibeam_ping_t>(e.data);
            EXPECT_EQ(p.num_beams, 480);
            EXPECT_EQ(p.utime_gps, 0);  // no NovAtel: no GPS time, and it says so
            EXPECT_EQ(p.gps_time_source, pitmap::multibeam_ping_t::TIME_SOURCE_NONE);
            ++pings;
        }
    }
    EXPECT_GE(raw_index, 40u);
    EXPECT_GE(pings + 1, static_cast<int>(raw_index));
}

// Issue 14 case 10: where a UDP channel listens is said at start-up; without bind_address it
// is the interface facing the allowed sender, 0.0.0.0 only when configured and then loudly.
TEST(AcqdProcessTest, UdpStartupSaysWhereItListens) {
    const std::string dir = testing::FreshDir("acqd_udp_bind");
    const auto config = [&](const std::string& bind) {
        return "lcm_url: \"memq://\"\nlog:\n  directory: " + dir +
               "/logs\n  min_free_bytes: 0\nchannels:\n  - id: mb\n    protocol: deltat_83p\n"
               "    udp: {" +
               bind +
               "allowed_senders: [127.0.0.1], port: " + std::to_string(testing::FreeUdpPort()) +
               "}\n    ec: {enabled: true, range_m: 30}\n";
    };
    for (const bool wildcard : {false, true}) {
        WriteText(dir + "/c.yaml", config(wildcard ? "bind_address: 0.0.0.0, " : ""));
        const Child c = Spawn({"--config", dir + "/c.yaml"},
                              dir + (wildcard ? "/err_wildcard.txt" : "/err_default.txt"));
        ASSERT_TRUE(
            WaitFor([&] { return ReadText(c.err_path).find("running") != std::string::npos; }));
        kill(c.pid, SIGTERM);
        EXPECT_EQ(Wait(c.pid), 0);
        const std::string err = ReadText(c.err_path);
        const std::string expected = wildcard ? "bound to 0.0.0.0:" : "bound to 127.0.0.1:";
        EXPECT_NE(err.find(expected), std::string::npos) << err;
        EXPECT_EQ(err.find("EVERY interface") != std::string::npos, wildcard) << err;
        EXPECT_NE(err.find("EC frames only to 127.0.0.1"), std::string::npos) << err;
    }
}

TEST(AcqdProcessTest, SigtermFlushesAndSighupRotates) {
    const std::string dir = testing::FreshDir("acqd_signals");
    const int port = testing::FreeUdpPort();
    WriteText(dir + "/c.yaml", UdpConfig(dir, port));
    const Child c = Spawn({"--config", dir + "/c.yaml"}, dir + "/err.txt");
    ASSERT_TRUE(WaitFor([&] { return ReadText(c.err_path).find("running") != std::string::npos; }));
    std::vector<std::vector<std::uint8_t>> sent;
    SendPings(port, dir + "/logs", 10, sent);
    kill(c.pid, SIGHUP);
    ASSERT_TRUE(
        WaitFor([&] { return ReadText(c.err_path).find("rotating") != std::string::npos; }));
    const std::size_t before = sent.size();
    SendPings(port, dir + "/logs", static_cast<int>(before) + 10, sent);
    kill(c.pid, SIGTERM);
    EXPECT_EQ(Wait(c.pid), 0) << ReadText(c.err_path);
    int files = 0;
    for (const auto& e : std::filesystem::directory_iterator(dir + "/logs")) {
        files += e.path().extension() == ".lcmlog";
    }
    EXPECT_GE(files, 2);
    // After a clean exit every datagram the kernel delivered is in the log, none twice.
    std::vector<std::vector<std::uint8_t>> logged;
    for (const auto& e : testing::ReadLogDir(dir + "/logs")) {
        if (e.channel == "RAW_MB") logged.push_back(DecodeAs<pitmap::raw_bytes_t>(e.data).data);
    }
    ASSERT_LE(logged.size(), sent.size());
    for (std::size_t i = 0; i < logged.size(); ++i) EXPECT_EQ(logged[i], sent[i]);
    EXPECT_GE(logged.size() + 2, sent.size());
}

TEST(AcqdProcessTest, FullDiskStopsLoggingButNotTheDaemon) {
    const std::string dir = testing::FreshDir("acqd_fulldisk");
    const std::string capture = std::string(PITMAP_TEST_DATA_DIR) + "/novatel/oem7drv_ins2.gps";
    WriteText(dir + "/c.yaml", FileReplayConfig(dir, capture));
    // 64 KiB of file: the log fills up long before the capture is through.
    const Child c = Spawn({"--config", dir + "/c.yaml"}, dir + "/err.txt", 64 * 1024);
    EXPECT_EQ(Wait(c.pid), 0) << ReadText(c.err_path);
    const auto events = testing::ReadLogDir(dir + "/logs");
    ASSERT_FALSE(events.empty());
    // What is there is a byte-exact prefix of the input.
    std::vector<std::uint8_t> raw;
    for (const auto& e : events) {
        if (e.channel == "RAW_NOV") {
            const auto r = DecodeAs<pitmap::raw_bytes_t>(e.data);
            raw.insert(raw.end(), r.data.begin(), r.data.end());
        }
    }
    const auto input = testing::ReadBytes(capture);
    ASSERT_LT(raw.size(), input.size());
    EXPECT_TRUE(std::equal(raw.begin(), raw.end(), input.begin()));
    std::uintmax_t total = 0;
    for (const auto& e : std::filesystem::directory_iterator(dir + "/logs")) {
        if (e.path().extension() == ".lcmlog") total += std::filesystem::file_size(e.path());
    }
    EXPECT_LE(total, 64u * 1024u * 2u);
}

}  // namespace
}  // namespace pitmap::acq
