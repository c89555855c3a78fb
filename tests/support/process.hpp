// SPDX-License-Identifier: MIT
// What the tests that run pitmap's programs as real processes share (the HIL test, the live HIL
// test, the scenario tests): a fresh work folder, a free loopback port, the HIL rig's command
// line, a child process with its output in a file, waiting for it with a deadline, and reading
// that output back.
#pragma once

#include <gtest/gtest.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <thread>
#include <vector>

#include "tests/support/work_dir.hpp"

namespace pitmap::test {

// TempDir()/NAME_PID, emptied and created; removed after the test program if all passed.
inline std::filesystem::path FreshDir(const std::string& name) {
    return MakeWorkDir(std::filesystem::path(::testing::TempDir()) /
                       (name + "_" + std::to_string(::getpid())));
}

// A port on 127.0.0.1 that was free a moment ago (SOCK_STREAM or SOCK_DGRAM); -1 on failure.
inline int FreePort(int type) {
    const int fd = ::socket(AF_INET, type, 0);
    if (fd < 0) return -1;
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t len = sizeof(a);
    int port = -1;
    if (::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof(a)) == 0 &&
        ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len) == 0) {
        port = ntohs(a.sin_port);
    }
    ::close(fd);
    return port;
}

// `pitmap-sim hil`: the demo survey for duration_s in real time, NovAtel on the pseudo-terminal
// `pty` and TCP tcp_port, Delta T on UDP udp_port, logged by pitmap-acqd into `out`; `extra`
// arguments appended (faults, an LCM URL).
inline std::vector<std::string> HilRigArgs(const std::filesystem::path& bin,
                                           double duration_s,
                                           const std::filesystem::path& out,
                                           const std::filesystem::path& pty,
                                           int tcp_port,
                                           int udp_port,
                                           const std::vector<std::string>& extra) {
    std::vector<std::string> args = {(bin / "pitmap-sim").string(),
                                     "hil",
                                     "--scenario",
                                     "demo",
                                     "--duration",
                                     std::to_string(duration_s),
                                     "--out",
                                     out.string(),
                                     "--acqd",
                                     (bin / "pitmap-acqd").string(),
                                     "--pty",
                                     pty.string(),
                                     "--tcp-port",
                                     std::to_string(tcp_port),
                                     "--udp-port",
                                     std::to_string(udp_port)};
    args.insert(args.end(), extra.begin(), extra.end());
    return args;
}

// Starts args[0] (a path) with args, stdout and stderr to the file `output`.
inline pid_t Spawn(const std::vector<std::string>& args, const std::string& output) {
    const pid_t pid = ::fork();
    if (pid == 0) {
        std::FILE* f = std::freopen(output.c_str(), "w", stdout);
        if (f != nullptr) ::dup2(::fileno(stdout), 2);
        std::vector<char*> argv;
        for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
        argv.push_back(nullptr);
        ::execv(argv[0], argv.data());
        ::_exit(127);
    }
    return pid;
}

// The exit code (128 + signal when killed by one) after waiting up to timeout_s; else -1, the
// child then stopped: with SIGTERM and `term_grace_s` to finish (when > 0), then SIGKILL.
inline int Wait(pid_t pid, double timeout_s, double term_grace_s = 0) {
    const auto wait_until = [pid](double seconds, int* status) {
        const auto deadline =
            std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
        while (std::chrono::steady_clock::now() < deadline) {
            if (::waitpid(pid, status, WNOHANG) == pid) return true;
            std::this_thread::sleep_for(std::chrono::milliseconds(50));
        }
        return false;
    };
    int status = 0;
    if (wait_until(timeout_s, &status)) {
        return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    }
    if (term_grace_s > 0) {
        ::kill(pid, SIGTERM);
        if (wait_until(term_grace_s, &status)) return -1;
    }
    ::kill(pid, SIGKILL);
    ::waitpid(pid, &status, 0);
    return -1;
}

// A whole text file ("" when it cannot be read).
inline std::string ReadText(const std::filesystem::path& p) {
    std::ifstream in(p);
    return std::string(std::istreambuf_iterator<char>(in), {});
}

}  // namespace pitmap::test
