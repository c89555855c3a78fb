// SPDX-License-Identifier: MIT
// Issue 14 case 7: what `pitmap-acqd --check-config` and the start-up check besides the YAML:
// the LCM URL (ValidateLcmUrl), the log directory (creatable, writable, a real disk), serial
// devices and UDP ports (warnings); every problem listed, exit 2 (1 at start-up).
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>

#include <arpa/inet.h>

#include <filesystem>

#include "firmware_host/daemon/startup_check.hpp"
#include "tests/firmware_host/daemon/acqd_process_util.hpp"

namespace pitmap::acq {
namespace {

bool Has(const std::vector<std::string>& v, const std::string& part) {
    for (const auto& s : v) {
        if (s.find(part) != std::string::npos) return true;
    }
    return false;
}

TEST(StartupCheckTest, LcmUrls) {
    for (const char* good : {"",
                             "memq://",
                             "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608",
                             "udpm://239.255.76.67:7667",
                             "file:///var/tmp/x.lcmlog?mode=w",
                             "file:///var/tmp/x.lcmlog?mode=a",
                             "tcpq://",
                             "tcpq://127.0.0.1:7700",
                             "mpudpm://239.255.76.67:7667?nports=4"}) {
        EXPECT_TRUE(ValidateLcmUrl(good).empty()) << good << ": " << ValidateLcmUrl(good)[0];
    }
    struct Bad {
        const char* url;
        const char* says;
    };
    for (const Bad& bad : {Bad{"bogus://x", "not one of udpm"},
                           Bad{"memq", "provider://"},
                           Bad{"udpm://", "multicast group and port"},
                           Bad{"udpm://10.0.0.1:7667", "multicast group"},
                           Bad{"udpm://239.255.76.67:99999", "multicast group and port"},
                           Bad{"udpm://239.255.76.67:7667?ttl", "not key=value"},
                           Bad{"udpm://239.255.76.67:7667?ttl=300", "ttl=300"},
                           Bad{"udpm://239.255.76.67:7667?tll=1", "unknown udpm option 'tll'"},
                           Bad{"file:///x.lcmlog", "needs mode=w"},
                           Bad{"file:///x.lcmlog?mode=x", "mode=x"},
                           Bad{"file://?mode=w", "needs a path"},
                           Bad{"tcpq://localhost", "host:port"}}) {
        const auto p = ValidateLcmUrl(bad.url);
        EXPECT_TRUE(Has(p, bad.says)) << bad.url << " -> " << (p.empty() ? "ok" : p[0]);
        EXPECT_TRUE(Has(p, bad.url)) << "names the URL: " << bad.url;
    }
}

TEST(StartupCheckTest, LogDirectories) {
    const std::string dir = testing::FreshDir("startup_check_dirs");
    testing::WriteText(dir + "/file", "x");
    EXPECT_TRUE(Has(CheckLogDirectory(dir + "/file"), "is not a directory"));
    EXPECT_FALSE(CheckLogDirectory(dir + "/file/logs").empty());
    EXPECT_FALSE(CheckLogDirectory("/proc/pitmap-logs").empty());
    EXPECT_FALSE(CheckLogDirectory("/proc/self").empty());
    EXPECT_FALSE(CheckLogDirectory("/sys/kernel").empty());
    // Missing: made for the probe and removed again; an existing one keeps no probe file.
    EXPECT_TRUE(CheckLogDirectory(dir + "/a/b/logs").empty());
    EXPECT_FALSE(std::filesystem::exists(dir + "/a"));
    EXPECT_TRUE(CheckLogDirectory(dir).empty());
    EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir), {}), 1);  // only "file"
}

// A config with four problems of the host: the log directory is a regular file, the LCM URL
// has no such provider (those two are errors), the serial device is not there and the UDP
// port is taken (warnings).
std::string HostProblemsConfig(const std::string& dir, int port, const std::string& lcm_url) {
    return "lcm_url: \"" + lcm_url + "\"\nlog:\n  directory: " + dir +
           "/file\n  fallback_dir: /proc/pitmap-fallback\n"
           "channels:\n  - id: nov\n    protocol: novatel\n"
           "    serial: {path: /dev/pitmap-no-such-tty, baud: 115200}\n"
           "  - id: mb\n    protocol: deltat_83p\n"
           "    udp: {bind_address: 127.0.0.1, allowed_senders: [127.0.0.1], port: " +
           std::to_string(port) + "}\n";
}

TEST(AcqdConfigCheckTest, CheckConfigListsHostProblemsAndWarnings) {
    const std::string dir = testing::FreshDir("acqd_check_host");
    testing::WriteText(dir + "/file", "x");
    const testing::BoundUdp taken;
    testing::WriteText(dir + "/c.yaml", HostProblemsConfig(dir, taken.port, "bogus://x"));
    const pid_t pid =
        testing::SpawnAcqd({"--config", dir + "/c.yaml", "--check-config"}, dir + "/err.txt");
    EXPECT_EQ(testing::WaitExit(pid), 2);
    const std::string err = testing::ReadText(dir + "/err.txt");
    for (const char* expected : {"2 problem(s)",
                                 "log.directory: ",
                                 "/file is not a directory",
                                 "bogus://x",
                                 "warning: log.fallback_dir",
                                 "warning: channels[0] (nov): serial device "
                                 "/dev/pitmap-no-such-tty",
                                 "warning: channels[1] (mb): UDP 127.0.0.1:"}) {
        EXPECT_NE(err.find(expected), std::string::npos) << "missing: " << expected << "\n" << err;
    }
    EXPECT_NE(err.find("in use"), std::string::npos) << err;
}

TEST(AcqdConfigCheckTest, WarningsAloneDoNotFailTheCheck) {
    const std::string dir = testing::FreshDir("acqd_check_warn");
    const testing::BoundUdp taken;
    testing::WriteText(dir + "/c.yaml",
                       "lcm_url: \"memq://\"\nlog:\n  directory: " + dir +
                           "/logs\nchannels:\n  - id: nov\n    protocol: novatel\n"
                           "    serial: {path: /dev/pitmap-no-such-tty, baud: 115200}\n");
    const pid_t pid =
        testing::SpawnAcqd({"--config", dir + "/c.yaml", "--check-config"}, dir + "/err.txt");
    EXPECT_EQ(testing::WaitExit(pid), 0) << testing::ReadText(dir + "/err.txt");
    EXPECT_NE(testing::ReadText(dir + "/err.txt").find("warning: channels[0]"), std::string::npos);
}

// Issue 34: /dev/null is a character device but no serial port: the daemon would open it, read
// nothing and retry for ever. --check-config refuses it (exit 2), start-up too (exit 1).
TEST(AcqdConfigCheckTest, SerialPathThatIsNotATerminalIsAProblem) {
    const std::string dir = testing::FreshDir("acqd_check_notty");
    testing::WriteText(dir + "/plain", "not a device");
    testing::WriteText(dir + "/c.yaml",
                       "lcm_url: \"memq://\"\nlog:\n  directory: " + dir +
                           "/logs\nchannels:\n  - id: nov\n    protocol: novatel\n"
                           "    serial: {path: /dev/null, baud: 115200}\n"
                           "  - id: nov2\n    protocol: novatel\n"
                           "    serial: {path: " +
                           dir + "/plain, baud: 115200}\n");
    pid_t pid =
        testing::SpawnAcqd({"--config", dir + "/c.yaml", "--check-config"}, dir + "/err.txt");
    EXPECT_EQ(testing::WaitExit(pid), 2);
    std::string err = testing::ReadText(dir + "/err.txt");
    EXPECT_NE(err.find("2 problem(s)"), std::string::npos) << err;
    EXPECT_NE(err.find("channels[0] (nov): serial device /dev/null is not a terminal device"),
              std::string::npos)
        << err;
    EXPECT_NE(err.find("channels[1] (nov2): serial device " + dir + "/plain is not a character"),
              std::string::npos)
        << err;
    EXPECT_EQ(err.find("warning: channels[0]"), std::string::npos) << err;
    pid = testing::SpawnAcqd({"--config", dir + "/c.yaml"}, dir + "/err2.txt");
    EXPECT_EQ(testing::WaitExit(pid), 1);
    err = testing::ReadText(dir + "/err2.txt");
    EXPECT_NE(err.find("/dev/null is not a terminal device"), std::string::npos) << err;
    EXPECT_EQ(err.find("running"), std::string::npos) << err;
}

TEST(AcqdConfigCheckTest, StartUpChecksTheHostBeforeStartingAndListsEverything) {
    const std::string dir = testing::FreshDir("acqd_check_start");
    // Valid YAML, but the log directory is under /proc and the fallback too: exit 1 at
    // start-up, both named, nothing started (no "running").
    testing::WriteText(dir + "/c.yaml",
                       "lcm_url: \"memq://\"\nlog:\n  directory: /proc/pitmap-logs\n"
                       "channels:\n  - id: nov\n    protocol: novatel\n"
                       "    file: {path: " +
                           dir + "/c.yaml}\n");
    const pid_t pid = testing::SpawnAcqd({"--config", dir + "/c.yaml"}, dir + "/err.txt");
    EXPECT_EQ(testing::WaitExit(pid), 1);
    const std::string err = testing::ReadText(dir + "/err.txt");
    EXPECT_NE(err.find("log.directory: cannot create /proc/pitmap-logs"), std::string::npos) << err;
    EXPECT_EQ(err.find("running"), std::string::npos) << err;
}

TEST(AcqdConfigCheckTest, ConfigThatIsADirectory) {
    const std::string work = testing::FreshDir("acqd_check_dir");
    const std::string dir = work + "/config.d";  // the "config": a directory
    std::filesystem::create_directories(dir);
    const pid_t pid = testing::SpawnAcqd({"--config", dir, "--check-config"}, work + "/err.txt");
    EXPECT_EQ(testing::WaitExit(pid), 2);
    const std::string err = testing::ReadText(work + "/err.txt");
    EXPECT_NE(err.find(dir + ": is a directory"), std::string::npos) << err;
    EXPECT_EQ(err.find("log: required"), std::string::npos) << err;
}

}  // namespace
}  // namespace pitmap::acq
