// SPDX-License-Identifier: MIT
// Helpers for the tests that run the real pitmap-acqd binary: spawning it with stderr in a
// file, waiting for it, bounded polling, reading what it logged, and the small fake devices
// (a NovAtel receiver answering LOG commands) the end-to-end tests put in front of it.
#pragma once

#include <fcntl.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdint>
#include <fstream>
#include <iterator>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "pitmap/channel_status_t.hpp"
#include "pitmap/raw_bytes_t.hpp"
#include "tests/firmware_host/daemon/acq_test_util.hpp"

namespace pitmap::acq::testing {

inline const std::string& AcqdBinary() {
    static const std::string bin = std::string(PITMAP_BIN_DIR) + "/pitmap-acqd";
    return bin;
}

// Starts pitmap-acqd with `args`, stdout and stderr into `err_path`. Returns the pid.
inline pid_t SpawnAcqd(const std::vector<std::string>& args, const std::string& err_path) {
    const pid_t pid = fork();
    if (pid == 0) {
        const int fd = ::open(err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        ::dup2(fd, 2);
        ::dup2(fd, 1);
        std::vector<char*> argv;
        argv.push_back(const_cast<char*>(AcqdBinary().c_str()));
        for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
        argv.push_back(nullptr);
        ::execv(AcqdBinary().c_str(), argv.data());
        _exit(127);
    }
    return pid;
}

// Exit code, or 128 + signal.
inline int WaitExit(pid_t pid) {
    int status = 0;
    while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
    }
    if (WIFEXITED(status)) return WEXITSTATUS(status);
    return 128 + WTERMSIG(status);
}

inline std::string ReadText(const std::string& path) {
    std::ifstream in(path);
    return std::string(std::istreambuf_iterator<char>(in), {});
}

inline void WriteText(const std::string& path, const std::string& text) {
    std::ofstream out(path);
    out << text;
}

// Polls `pred` every 10 ms until it holds or `max_ms` passed. Bounds the test; the outcome
// never depends on how long it took.
template <typename P>
bool WaitFor(P pred, int max_ms = 15'000) {
    for (int i = 0; i < max_ms / 10; ++i) {
        if (pred()) return true;
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return pred();
}

// The RAW_<ID> payloads of a log, concatenated, with the sequence numbers checked.
inline std::vector<std::uint8_t> RawBytesOf(const std::vector<LogEvent>& events,
                                            const std::string& channel) {
    std::vector<std::uint8_t> out;
    std::int64_t seq = 0;
    for (const auto& e : events) {
        if (e.channel != channel) continue;
        const auto r = DecodeAs<pitmap::raw_bytes_t>(e.data);
        EXPECT_EQ(r.seq, seq++);
        out.insert(out.end(), r.data.begin(), r.data.end());
    }
    return out;
}

// Bytes of RAW_<ID> in the log directory so far (complete events only).
inline std::size_t LoggedRawBytes(const std::string& dir, const std::string& channel) {
    std::size_t n = 0;
    for (const auto& e : ReadLogDir(dir)) {
        if (e.channel == channel) n += DecodeAs<pitmap::raw_bytes_t>(e.data).data.size();
    }
    return n;
}

// Frame kind -> count of a channel_status_t.
inline std::map<std::string, std::int64_t> FrameKinds(const pitmap::channel_status_t& s) {
    std::map<std::string, std::int64_t> m;
    for (int i = 0; i < s.num_frame_kinds; ++i) m[s.frame_kind[i]] = s.frame_count[i];
    return m;
}

// frames_by_id of tests/data/novatel/golden/<name>.json.
inline std::map<std::string, std::int64_t> GoldenFrames(const std::string& name) {
    std::ifstream in(std::string(PITMAP_TEST_DATA_DIR) + "/novatel/golden/" + name + ".json");
    const nlohmann::json golden = nlohmann::json::parse(in);
    std::map<std::string, std::int64_t> m;
    for (const auto& [k, v] : golden["frames_by_id"].items()) m[k] = v.get<std::int64_t>();
    return m;
}

// Writes all of `bytes` to a (possibly non-blocking) fd, waiting with poll when it is full.
// False when the fd fails or stays full for `timeout_ms`.
inline bool WriteAll(int fd, const std::uint8_t* data, std::size_t size, int timeout_ms = 5000) {
    std::size_t done = 0;
    while (done < size) {
        const ssize_t n = ::write(fd, data + done, size - done);
        if (n > 0) {
            done += static_cast<std::size_t>(n);
            continue;
        }
        if (n < 0 && errno == EINTR) continue;
        if (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK) return false;
        pollfd p{fd, POLLOUT, 0};
        if (::poll(&p, 1, timeout_ms) <= 0) return false;
    }
    return true;
}

// The receiver side of the set-up handshake: reads command lines (CR LF terminated) from `fd`
// and answers each with `answer` until `count` commands arrived. The lines are returned;
// fewer than `count` when nothing came for `timeout_ms`. Every answer is appended to
// `written` (the bytes the daemon must log).
inline std::vector<std::string> AnswerCommands(int fd,
                                               std::size_t count,
                                               const std::string& answer,
                                               std::vector<std::uint8_t>& written,
                                               int timeout_ms = 10'000) {
    std::vector<std::string> lines;
    std::string pending;
    while (lines.size() < count) {
        pollfd p{fd, POLLIN, 0};
        if (::poll(&p, 1, timeout_ms) <= 0) break;
        char buf[512];
        const ssize_t n = ::read(fd, buf, sizeof(buf));
        if (n < 0 && (errno == EINTR || errno == EAGAIN)) continue;
        if (n <= 0) break;
        pending.append(buf, static_cast<std::size_t>(n));
        std::size_t eol;
        while ((eol = pending.find("\r\n")) != std::string::npos) {
            lines.push_back(pending.substr(0, eol));
            pending.erase(0, eol + 2);
            const auto* a = reinterpret_cast<const std::uint8_t*>(answer.data());
            if (!WriteAll(fd, a, answer.size())) return lines;
            written.insert(written.end(), a, a + answer.size());
        }
    }
    return lines;
}

// Writes `data` in cycled odd-sized chunks (1, 7, 13, ... bytes), yielding between chunks so
// the reader sees many small reads. Appends to `written`.
inline bool WriteInOddChunks(int fd,
                             const std::vector<std::uint8_t>& data,
                             std::vector<std::uint8_t>& written) {
    static constexpr std::size_t kSizes[] = {1, 7, 13, 61, 251, 1021, 4093, 3, 509};
    std::size_t pos = 0;
    for (std::size_t i = 0; pos < data.size(); ++i) {
        const std::size_t n = std::min(kSizes[i % std::size(kSizes)], data.size() - pos);
        if (!WriteAll(fd, data.data() + pos, n)) return false;
        written.insert(written.end(),
                       data.begin() + static_cast<long>(pos),
                       data.begin() + static_cast<long>(pos + n));
        pos += n;
        if (i % 8 == 7) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    return true;
}

}  // namespace pitmap::acq::testing
