// SPDX-License-Identifier: MIT
// RerunProcess: the page's "re-run" button. Spawns `program args...` (pitmap rerun P, the
// pitmap executable beside the server's own) as a child process with its stdout and stderr on
// one pipe, keeps the last lines it wrote (at most max_lines, each cut at 1000 bytes) and its
// exit status. One child at a time.
// Failure model: a program that cannot be started is an error from Start (naming it); a child
// killed by a signal reports exit_code 128 + signal. The destructor kills a child still running
// and its process group (SIGTERM, then SIGKILL after 5 s) and reaps it.
// Thread safety: every member may be called from any thread.
#pragma once

#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "common/result.hpp"

namespace pitmap::proc::edit {

struct RerunState {
    enum class Kind { kIdle, kRunning, kExited };
    Kind kind = Kind::kIdle;
    int exit_code = 0;               // kExited
    std::int64_t runs = 0;           // children started so far
    double seconds = 0;              // of the current or last child
    std::vector<std::string> lines;  // its last lines of output
};
const char* ToString(RerunState::Kind k);

class RerunProcess {
public:
    explicit RerunProcess(std::size_t max_lines = 200);
    ~RerunProcess();
    RerunProcess(const RerunProcess&) = delete;
    RerunProcess& operator=(const RerunProcess&) = delete;

    // Starts the child; an error when one is running or it cannot be started.
    Status Start(const std::string& program, const std::vector<std::string>& args);
    RerunState state() const;
    bool running() const;

private:
    void Reader(int fd, int pid);
    mutable std::mutex mutex_;
    std::size_t max_lines_;
    std::deque<std::string> lines_;
    RerunState::Kind kind_ = RerunState::Kind::kIdle;
    int exit_code_ = 0;
    std::int64_t runs_ = 0;
    int pid_ = -1;
    double started_s_ = 0, ended_s_ = 0;
    std::thread reader_;
};

}  // namespace pitmap::proc::edit
