// SPDX-License-Identifier: MIT
#include "firmware_host/io/detail/stream_source.hpp"

#include <poll.h>

#include <algorithm>
#include <cerrno>

namespace pitmap::acq::detail {

Status StreamSource::TryOpen() {
    set_state(SourceState::kConnecting);
    auto fd = OpenFd();
    if (!fd) {
        backoff_.Failed(MonotonicNowUs());
        set_state(SourceState::kDisconnected);
        return Fail(fd.error().message);
    }
    fd_ = std::move(*fd);
    backoff_.Succeeded();
    NoteOpened();
    return Ok{};
}

Status StreamSource::Open() {
    if (fd_.valid()) return Ok{};
    return TryOpen();
}

void StreamSource::Close() {
    fd_.Reset();
    backoff_.Succeeded();
    set_state(SourceState::kClosed);
}

Error StreamSource::Lost(const std::string& message) {
    fd_.Reset();
    backoff_.Failed(MonotonicNowUs());
    set_state(SourceState::kDisconnected);
    return Fail(message);
}

Expected<ReadOutcome> StreamSource::Read(Chunk& chunk, int timeout_ms) {
    const std::int64_t deadline = MonotonicNowUs() + std::max(timeout_ms, 0) * 1000LL;
    if (!fd_.valid()) {
        // Closed by the user or lost: wait for the backoff, then one reopen attempt.
        const std::int64_t now = MonotonicNowUs();
        if (!backoff_.Ready(now)) {
            const std::int64_t wake = std::min(deadline, backoff_.next_attempt_us());
            SleepMs(static_cast<int>((wake - now + 999) / 1000));
            if (!backoff_.Ready(MonotonicNowUs())) return ReadOutcome::kTimeout;
        }
        auto opened = TryOpen();
        if (!opened) return opened.error();
    }
    const std::int64_t left_us = deadline - MonotonicNowUs();
    const int left_ms = left_us <= 0 ? 0 : static_cast<int>((left_us + 999) / 1000);
    switch (PollFd(fd_.get(), POLLIN, left_ms)) {
        case PollResult::kTimeout:
            return ReadOutcome::kTimeout;
        case PollResult::kError:
            return Lost(ErrnoMessage(description() + ": poll", errno));
        case PollResult::kHangup:
        case PollResult::kReady:
            break;
    }
    chunk.data.resize(read_buffer_bytes_);
    chunk.utime_kernel = 0;
    chunk.truncated = false;
    long n;
    do {
        n = ReadSome(fd_.get(), chunk.data.data(), chunk.data.size(), chunk.utime_kernel);
    } while (n < 0 && errno == EINTR);
    chunk.utime_host = HostNowUtime();
    if (n > 0) {
        chunk.data.resize(static_cast<std::size_t>(n));
        chunk.peer = peer();
        return ReadOutcome::kData;
    }
    if (n == 0) return Lost(description() + ": end of stream (device or peer gone)");
    if (errno == EAGAIN || errno == EWOULDBLOCK) return ReadOutcome::kTimeout;
    return Lost(ErrnoMessage(description() + ": read", errno));
}

Status StreamSource::Write(std::span<const std::byte> bytes, int timeout_ms) {
    if (!fd_.valid()) return Fail(description() + ": write while not open");
    const std::int64_t deadline = MonotonicNowUs() + std::max(timeout_ms, 0) * 1000LL;
    std::size_t done = 0;
    while (done < bytes.size()) {
        const long n = WriteSome(fd_.get(), bytes.data() + done, bytes.size() - done);
        if (n > 0) {
            done += static_cast<std::size_t>(n);
            continue;
        }
        if (n < 0 && errno == EINTR) continue;
        if (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK) {
            return Lost(ErrnoMessage(description() + ": write", errno));
        }
        const std::int64_t left_us = deadline - MonotonicNowUs();
        if (left_us <= 0) {
            return Fail(description() + ": write timed out after " + std::to_string(done) + " of " +
                        std::to_string(bytes.size()) + " bytes");
        }
        const PollResult p = PollFd(fd_.get(), POLLOUT, static_cast<int>((left_us + 999) / 1000));
        if (p == PollResult::kHangup || p == PollResult::kError) {
            return Lost(description() + ": device gone while writing");
        }
    }
    return Ok{};
}

}  // namespace pitmap::acq::detail
