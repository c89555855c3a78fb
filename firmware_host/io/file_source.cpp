// SPDX-License-Identifier: MIT
#include "firmware_host/io/file_source.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <utility>

namespace pitmap::acq {

std::vector<std::string> FileSourceConfig::Validate() const {
    std::vector<std::string> problems;
    if (path.empty()) problems.push_back("file: path is empty");
    if (chunk_bytes == 0) problems.push_back("file: chunk_bytes must be > 0");
    if (!(bytes_per_second >= 0.0) || !std::isfinite(bytes_per_second)) {
        problems.push_back("file: bytes_per_second must be >= 0");
    }
    return problems;
}

FileSource::FileSource(FileSourceConfig config) : config_(std::move(config)) {
    PITMAP_CHECK(config_.Validate().empty(), "FileSource: invalid config");
}

Status FileSource::Open() {
    if (fd_.valid()) return Ok{};
    fd_.Reset(::open(config_.path.c_str(), O_RDONLY | O_CLOEXEC));
    if (!fd_.valid()) {
        set_state(SourceState::kDisconnected);
        return Fail(detail::ErrnoMessage("file: open " + config_.path, errno));
    }
    bytes_read_ = 0;
    start_us_ = 0;
    NoteOpened();
    return Ok{};
}

void FileSource::Close() {
    fd_.Reset();
    set_state(SourceState::kClosed);
}

Expected<ReadOutcome> FileSource::Read(Chunk& chunk, int timeout_ms) {
    if (state() == SourceState::kFinished) return ReadOutcome::kEndOfStream;
    if (!fd_.valid()) {
        auto opened = Open();
        if (!opened) return opened.error();
    }
    const std::int64_t now = MonotonicNowUs();
    if (start_us_ == 0) start_us_ = now;
    if (config_.bytes_per_second > 0.0) {
        // The next chunk is due when the bytes already delivered have "taken" their time.
        const auto due = start_us_ + static_cast<std::int64_t>(static_cast<double>(bytes_read_) /
                                                               config_.bytes_per_second * 1e6);
        if (due > now) {
            const std::int64_t wait_us = std::min<std::int64_t>(due - now, timeout_ms * 1000LL);
            detail::SleepMs(static_cast<int>((wait_us + 999) / 1000));
            if (MonotonicNowUs() < due) return ReadOutcome::kTimeout;
        }
    }
    chunk.data.resize(config_.chunk_bytes);
    long n;
    do {
        n = ::read(fd_.get(), chunk.data.data(), chunk.data.size());
    } while (n < 0 && errno == EINTR);
    chunk.utime_host = HostNowUtime();
    chunk.utime_kernel = 0;
    chunk.truncated = false;
    chunk.peer.clear();
    if (n < 0) return Fail(detail::ErrnoMessage("file: read " + config_.path, errno));
    if (n == 0) {
        fd_.Reset();
        set_state(SourceState::kFinished);
        return ReadOutcome::kEndOfStream;
    }
    chunk.data.resize(static_cast<std::size_t>(n));
    bytes_read_ += n;
    return ReadOutcome::kData;
}

Status FileSource::Write(std::span<const std::byte>, int) {
    return Fail("file: " + config_.path + " is a replay source and cannot be written");
}

}  // namespace pitmap::acq
