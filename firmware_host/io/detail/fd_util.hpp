// SPDX-License-Identifier: MIT
// Private helpers of io/: an owning file descriptor, poll with a timeout, errno text.
#pragma once

#include <cstdint>
#include <string>

namespace pitmap::acq::detail {

// Owns one file descriptor; closes it on destruction or Reset().
class UniqueFd {
public:
    UniqueFd() = default;
    explicit UniqueFd(int fd) : fd_(fd) {}
    ~UniqueFd() { Reset(); }
    UniqueFd(UniqueFd&& o) noexcept : fd_(o.Release()) {}
    UniqueFd& operator=(UniqueFd&& o) noexcept {
        if (this != &o) Reset(o.Release());
        return *this;
    }
    UniqueFd(const UniqueFd&) = delete;
    UniqueFd& operator=(const UniqueFd&) = delete;

    int get() const { return fd_; }
    bool valid() const { return fd_ >= 0; }
    int Release() {
        const int fd = fd_;
        fd_ = -1;
        return fd;
    }
    void Reset(int fd = -1);

private:
    int fd_ = -1;
};

enum class PollResult { kReady, kTimeout, kHangup, kError };
// Waits up to timeout_ms for `events` (POLLIN/POLLOUT) on fd, retrying on EINTR with the
// remaining time. kHangup: POLLHUP/POLLERR without POLLIN data (a vanished device).
PollResult PollFd(int fd, short events, int timeout_ms);

// "what: strerror(errno) (errno N)".
std::string ErrnoMessage(const std::string& what, int err);

// Unix microseconds from a CLOCK_REALTIME timespec.
std::int64_t UtimeFromTimespec(long sec, long nsec);

// Sleeps for up to `ms` (>= 0) milliseconds.
void SleepMs(int ms);

}  // namespace pitmap::acq::detail
