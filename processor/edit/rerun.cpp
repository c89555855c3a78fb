// SPDX-License-Identifier: MIT
#include "processor/edit/rerun.hpp"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>

extern char** environ;

namespace pitmap::proc::edit {

namespace {

double SteadyS() {
    return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch())
        .count();
}

constexpr std::size_t kMaxLineBytes = 1000;

}  // namespace

const char* ToString(RerunState::Kind k) {
    switch (k) {
        case RerunState::Kind::kIdle:
            return "idle";
        case RerunState::Kind::kRunning:
            return "running";
        case RerunState::Kind::kExited:
            return "exited";
    }
    return "?";
}

RerunProcess::RerunProcess(std::size_t max_lines) : max_lines_(max_lines) {}

RerunProcess::~RerunProcess() {
    int pid = -1;
    {
        std::lock_guard<std::mutex> lock(mutex_);
        if (kind_ == RerunState::Kind::kRunning) pid = pid_;
    }
    if (pid > 0) {
        ::kill(-pid, SIGTERM);  // its process group
        for (int i = 0; i < 50 && running(); ++i) ::usleep(100000);
        if (running()) ::kill(-pid, SIGKILL);
    }
    if (reader_.joinable()) reader_.join();
}

Status RerunProcess::Start(const std::string& program, const std::vector<std::string>& args) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (kind_ == RerunState::Kind::kRunning) return Error{"a re-run is already running"};
    if (reader_.joinable()) reader_.join();  // the last child's reader has finished
    int fds[2];
    if (::pipe2(fds, O_CLOEXEC) != 0) return Error{std::string("pipe: ") + std::strerror(errno)};
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_adddup2(&actions, fds[1], 1);
    posix_spawn_file_actions_adddup2(&actions, fds[1], 2);
    posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
    std::vector<std::string> argv_s = {program};
    argv_s.insert(argv_s.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (auto& a : argv_s) argv.push_back(a.data());
    argv.push_back(nullptr);
    pid_t pid = -1;
    // Its own process group: stopping it stops what it started too (pitmap-report), which
    // would otherwise hold the pipe open.
    posix_spawnattr_t attr;
    posix_spawnattr_init(&attr);
    posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETPGROUP);
    posix_spawnattr_setpgroup(&attr, 0);
    const int rc = ::posix_spawn(&pid, program.c_str(), &actions, &attr, argv.data(), environ);
    posix_spawnattr_destroy(&attr);
    posix_spawn_file_actions_destroy(&actions);
    ::close(fds[1]);
    if (rc != 0) {
        ::close(fds[0]);
        return Error{"cannot start " + program + ": " + std::strerror(rc)};
    }
    pid_ = pid;
    kind_ = RerunState::Kind::kRunning;
    ++runs_;
    lines_.clear();
    started_s_ = SteadyS();
    reader_ = std::thread([this, fd = fds[0], pid] { Reader(fd, pid); });
    return Ok{};
}

void RerunProcess::Reader(int fd, int pid) {
    std::string partial;
    char buf[4096];
    const auto push = [this](std::string line) {
        std::lock_guard<std::mutex> lock(mutex_);
        if (line.size() > kMaxLineBytes) line.resize(kMaxLineBytes);
        lines_.push_back(std::move(line));
        while (lines_.size() > max_lines_) lines_.pop_front();
    };
    for (;;) {
        const ssize_t n = ::read(fd, buf, sizeof buf);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) break;
        partial.append(buf, static_cast<std::size_t>(n));
        for (std::size_t at; (at = partial.find_first_of("\r\n")) != std::string::npos;) {
            if (at > 0) push(partial.substr(0, at));
            partial.erase(0, at + 1);
        }
        if (partial.size() > kMaxLineBytes) {
            push(partial);
            partial.clear();
        }
    }
    if (!partial.empty()) push(partial);
    ::close(fd);
    int status = 0;
    while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
    }
    std::lock_guard<std::mutex> lock(mutex_);
    exit_code_ = WIFEXITED(status)     ? WEXITSTATUS(status)
                 : WIFSIGNALED(status) ? 128 + WTERMSIG(status)
                                       : -1;
    kind_ = RerunState::Kind::kExited;
    ended_s_ = SteadyS();
}

RerunState RerunProcess::state() const {
    std::lock_guard<std::mutex> lock(mutex_);
    RerunState s;
    s.kind = kind_;
    s.exit_code = exit_code_;
    s.runs = runs_;
    s.seconds = kind_ == RerunState::Kind::kRunning  ? SteadyS() - started_s_
                : kind_ == RerunState::Kind::kExited ? ended_s_ - started_s_
                                                     : 0;
    s.lines.assign(lines_.begin(), lines_.end());
    return s;
}

bool RerunProcess::running() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return kind_ == RerunState::Kind::kRunning;
}

}  // namespace pitmap::proc::edit
