// SPDX-License-Identifier: MIT
// The shipped systemd unit (issue 14 case 11): `systemd-analyze verify` accepts it (on a copy
// whose ExecStart points at the built binary, since verify wants the command to exist), its
// offline security exposure stays low, and it, the tmpfiles.d and sysusers.d snippets and
// roaz.yaml agree on the user and the log directory, and the snippets apply. Skips where the
// systemd tools are missing.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <regex>
#include <string>
#include <vector>

#include "firmware_host/daemon/daemon_config.hpp"

namespace pitmap::acq {
namespace {

const std::string kConfigDir = std::string(PITMAP_SOURCE_DIR) + "/firmware_host/config/";

std::string ReadText(const std::string& path) {
    std::ifstream in(path);
    return std::string(std::istreambuf_iterator<char>(in), {});
}

struct ShellRun {
    int exit_code = -1;
    std::string output;  // stdout and stderr
};

ShellRun Shell(const std::string& command) {
    ShellRun r;
    std::FILE* p = ::popen((command + " 2>&1").c_str(), "r");
    if (p == nullptr) return r;
    char buf[4096];
    std::size_t n;
    while ((n = std::fread(buf, 1, sizeof(buf), p)) > 0) r.output.append(buf, n);
    const int status = ::pclose(p);
    r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    return r;
}

bool HaveSystemdAnalyze() {
    return Shell("command -v systemd-analyze").exit_code == 0;
}

// The unit with ExecStart/ExecStartPre on the built binary, in a fresh directory.
std::string UnitCopy() {
    // One directory per test: ctest runs them in parallel.
    const std::string dir = ::testing::TempDir() + "/systemd_unit_test_" +
                            ::testing::UnitTest::GetInstance()->current_test_info()->name();
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    const std::string unit = std::regex_replace(ReadText(kConfigDir + "pitmap-acqd.service"),
                                                std::regex("/usr/local/bin/pitmap-acqd"),
                                                std::string(PITMAP_BIN_DIR) + "/pitmap-acqd");
    const std::string path = dir + "/pitmap-acqd.service";
    std::ofstream(path) << unit;
    return path;
}

TEST(SystemdUnitTest, VerifyAcceptsTheUnit) {
    if (!HaveSystemdAnalyze()) GTEST_SKIP() << "systemd-analyze not installed";
    const ShellRun r = Shell("systemd-analyze verify '" + UnitCopy() + "'");
    EXPECT_EQ(r.exit_code, 0) << r.output;
    EXPECT_EQ(r.output.find("pitmap-acqd.service:"), std::string::npos) << r.output;
}

TEST(SystemdUnitTest, OfflineSecurityExposureIsLow) {
    if (!HaveSystemdAnalyze()) GTEST_SKIP() << "systemd-analyze not installed";
    const ShellRun r = Shell("systemd-analyze security --offline=true '" + UnitCopy() + "'");
    std::smatch m;
    if (!std::regex_search(
            r.output, m, std::regex("Overall exposure level for [^:]*: ([0-9.]+)"))) {
        GTEST_SKIP() << "no offline security analysis here (systemd < 252?): " << r.output;
    }
    // 9.6 (UNSAFE) for the unit before issue 14, 1.5 after.
    EXPECT_LE(std::stod(m[1].str()), 2.0) << r.output;
}

TEST(SystemdUnitTest, UnitSnippetsAndVehicleConfigAgree) {
    const std::string unit = ReadText(kConfigDir + "pitmap-acqd.service");
    const LoadedConfig roaz = LoadDaemonConfig(kConfigDir + "roaz.yaml");
    ASSERT_TRUE(roaz.problems.empty());
    const std::string log_dir = roaz.config.log.directory;
    for (const std::string& line : std::vector<std::string>{"User=pitmap",
                                                            "SupplementaryGroups=dialout",
                                                            "ReadWritePaths=" + log_dir,
                                                            "ProtectSystem=strict",
                                                            "NoNewPrivileges=yes",
                                                            "CapabilityBoundingSet=\n",
                                                            "DevicePolicy=closed",
                                                            "UMask=0027",
                                                            "SystemCallFilter=@system-service"}) {
        EXPECT_NE(unit.find(line), std::string::npos) << "unit lacks " << line;
    }
    EXPECT_EQ(unit.find("\nUser=root"), std::string::npos);
    EXPECT_NE(ReadText(kConfigDir + "pitmap-acqd.tmpfiles.conf")
                  .find("d " + log_dir + " 0750 pitmap pitmap"),
              std::string::npos);
    EXPECT_NE(ReadText(kConfigDir + "pitmap-acqd.sysusers.conf").find("\nu pitmap "),
              std::string::npos);
}

// The sysusers.d and tmpfiles.d snippets applied to a scratch root: user and group pitmap,
// member of dialout, and the log directory 0750 owned by them.
TEST(SystemdUnitTest, SnippetsApplyInAScratchRoot) {
    if (Shell("command -v systemd-sysusers && command -v systemd-tmpfiles").exit_code != 0) {
        GTEST_SKIP() << "systemd-sysusers or systemd-tmpfiles not installed";
    }
    if (::geteuid() != 0) GTEST_SKIP() << "systemd-tmpfiles needs root to chown";
    const std::string root = ::testing::TempDir() + "/systemd_unit_root";
    std::filesystem::remove_all(root);
    std::filesystem::create_directories(root + "/etc");
    const ShellRun users = Shell("systemd-sysusers --root='" + root + "' '" + kConfigDir +
                                 "pitmap-acqd.sysusers.conf'");
    ASSERT_EQ(users.exit_code, 0) << users.output;
    const std::string passwd = ReadText(root + "/etc/passwd");
    std::smatch m;
    ASSERT_TRUE(std::regex_search(passwd, m, std::regex("(^|\n)pitmap:x:([0-9]+):([0-9]+):")))
        << passwd;
    EXPECT_TRUE(std::regex_search(ReadText(root + "/etc/group"),
                                  std::regex("(^|\n)dialout:x:[0-9]+:pitmap\n")));
    const ShellRun files = Shell("systemd-tmpfiles --root='" + root + "' --create '" + kConfigDir +
                                 "pitmap-acqd.tmpfiles.conf'");
    ASSERT_EQ(files.exit_code, 0) << files.output;
    const LoadedConfig roaz = LoadDaemonConfig(kConfigDir + "roaz.yaml");
    struct stat st {};
    ASSERT_EQ(::stat((root + roaz.config.log.directory).c_str(), &st), 0);
    EXPECT_TRUE(S_ISDIR(st.st_mode));
    EXPECT_EQ(st.st_mode & 07777, 0750u);
    EXPECT_EQ(st.st_uid, static_cast<uid_t>(std::stoul(m[2].str())));
    EXPECT_EQ(st.st_gid, static_cast<gid_t>(std::stoul(m[3].str())));
}

}  // namespace
}  // namespace pitmap::acq
