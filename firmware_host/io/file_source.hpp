// SPDX-License-Identifier: MIT
// FileSource: replays a capture file through the ByteSource interface, in chunks of a set
// size, optionally paced to a byte rate, so offline tests and replays use the daemon's own
// code path. Chunks carry the host time at which they were read; Read() returns
// kEndOfStream at the end of the file (the source is then kFinished).
//
// THREADING: as ByteSource (one owner thread).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "firmware_host/io/byte_source.hpp"
#include "firmware_host/io/detail/fd_util.hpp"

namespace pitmap::acq {

struct FileSourceConfig {
    std::string path;                // the file to replay
    std::size_t chunk_bytes = 4096;  // bytes per chunk (the last one may be shorter)
    double bytes_per_second = 0.0;   // pacing; 0 = as fast as the reader asks

    std::vector<std::string> Validate() const;
};

class FileSource final : public ByteSource {
public:
    // Precondition: config.Validate() is empty.
    explicit FileSource(FileSourceConfig config);

    Status Open() override;
    Expected<ReadOutcome> Read(Chunk& chunk, int timeout_ms) override;
    // Files are read-only: always fails.
    Status Write(std::span<const std::byte> bytes, int timeout_ms) override;
    void Close() override;
    Transport transport() const override { return Transport::kFile; }
    std::string description() const override { return "file " + config_.path; }

    std::int64_t bytes_read() const { return bytes_read_; }

private:
    FileSourceConfig config_;
    detail::UniqueFd fd_;
    std::int64_t bytes_read_ = 0;
    std::int64_t start_us_ = 0;  // monotonic time of the first read, for pacing
};

}  // namespace pitmap::acq
