// SPDX-License-Identifier: MIT
#include "firmware_host/io/detail/fd_util.hpp"

#include <poll.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <ctime>

#include "firmware_host/io/byte_source.hpp"

namespace pitmap::acq {

const char* ToString(SourceState state) {
    switch (state) {
        case SourceState::kClosed:
            return "closed";
        case SourceState::kConnecting:
            return "connecting";
        case SourceState::kOpen:
            return "open";
        case SourceState::kDisconnected:
            return "disconnected";
        case SourceState::kFinished:
            return "finished";
    }
    return "unknown";
}

std::int64_t HostNowUtime() {
    timespec ts{};
    clock_gettime(CLOCK_REALTIME, &ts);
    return detail::UtimeFromTimespec(ts.tv_sec, ts.tv_nsec);
}

std::int64_t MonotonicNowUs() {
    timespec ts{};
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return detail::UtimeFromTimespec(ts.tv_sec, ts.tv_nsec);
}

namespace detail {

void UniqueFd::Reset(int fd) {
    if (fd_ >= 0) {
        // close() must not be retried on EINTR on Linux: the descriptor is gone either way.
        ::close(fd_);
    }
    fd_ = fd;
}

PollResult PollFd(int fd, short events, int timeout_ms) {
    const std::int64_t deadline = MonotonicNowUs() + static_cast<std::int64_t>(timeout_ms) * 1000;
    for (;;) {
        pollfd p{fd, events, 0};
        const std::int64_t left_us = deadline - MonotonicNowUs();
        const int left_ms = left_us <= 0 ? 0 : static_cast<int>((left_us + 999) / 1000);
        const int n = ::poll(&p, 1, left_ms);
        if (n < 0) {
            if (errno == EINTR) continue;
            return PollResult::kError;
        }
        if (n == 0) return PollResult::kTimeout;
        if (p.revents & events) return PollResult::kReady;
        if (p.revents & POLLNVAL) return PollResult::kError;
        if (p.revents & (POLLHUP | POLLERR)) return PollResult::kHangup;
        if (left_ms == 0) return PollResult::kTimeout;
    }
}

std::string ErrnoMessage(const std::string& what, int err) {
    return what + ": " + std::strerror(err) + " (errno " + std::to_string(err) + ")";
}

std::int64_t UtimeFromTimespec(long sec, long nsec) {
    return static_cast<std::int64_t>(sec) * 1'000'000 + static_cast<std::int64_t>(nsec) / 1000;
}

void SleepMs(int ms) {
    if (ms <= 0) return;
    timespec ts{ms / 1000, static_cast<long>(ms % 1000) * 1'000'000L};
    while (nanosleep(&ts, &ts) != 0 && errno == EINTR) {
    }
}

}  // namespace detail
}  // namespace pitmap::acq
