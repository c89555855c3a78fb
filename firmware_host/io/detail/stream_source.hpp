// SPDX-License-Identifier: MIT
// Shared machinery of the connection-like sources (serial, TCP client): an fd, reopen with
// bounded backoff from Read(), reads with a timeout, writes with a timeout.
//
// THREADING: as ByteSource (one owner thread).
#pragma once

#include <cstdint>
#include <span>
#include <string>

#include "firmware_host/io/backoff.hpp"
#include "firmware_host/io/byte_source.hpp"
#include "firmware_host/io/detail/fd_util.hpp"

namespace pitmap::acq::detail {

class StreamSource : public ByteSource {
public:
    Status Open() override;
    Expected<ReadOutcome> Read(Chunk& chunk, int timeout_ms) override;
    Status Write(std::span<const std::byte> bytes, int timeout_ms) override;
    void Close() override;

protected:
    StreamSource(const BackoffConfig& backoff, std::size_t read_buffer_bytes)
        : backoff_(backoff), read_buffer_bytes_(read_buffer_bytes) {}

    // Opens and configures the device; returns the ready descriptor.
    virtual Expected<UniqueFd> OpenFd() = 0;
    // One read of up to `capacity` bytes into `dst` (fd is readable). Returns the count, 0 for
    // end of stream (peer closed / device gone), or -1 with errno set. May set utime_kernel.
    virtual long ReadSome(int fd,
                          std::byte* dst,
                          std::size_t capacity,
                          std::int64_t& utime_kernel) = 0;
    virtual long WriteSome(int fd, const std::byte* src, std::size_t size) = 0;
    // "peer" string for the chunks.
    virtual std::string peer() const = 0;

    // Marks the device lost: closes the fd, schedules a reopen; returns the error for Read().
    Error Lost(const std::string& message);

private:
    Status TryOpen();

    UniqueFd fd_;
    Backoff backoff_;
    std::size_t read_buffer_bytes_;
};

}  // namespace pitmap::acq::detail
