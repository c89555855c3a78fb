// SPDX-License-Identifier: MIT
// ByteSource: the one interface through which the daemon receives bytes from a device.
//
// Implementations (serial_source.hpp, tcp_client_source.hpp, udp_source.hpp, file_source.hpp)
// are the only code of the daemon that owns file descriptors. Every call returns its failures
// as values (pitmap::Expected / pitmap::Status); nothing throws and nothing aborts on device
// trouble. A source that loses its device (USB adapter unplugged, TCP peer gone) moves to
// SourceState::kDisconnected and reopens by itself from Read(), with a bounded exponential
// backoff (see backoff.hpp), so a reader thread just keeps calling Read().
//
// THREADING: a source is owned by one thread (the channel's reader thread), which makes every
// call, including Write()/SendTo() for commands. Only the const accessors state(),
// reconnects(), generation(), kernel_drops() may be called from other threads (atomics).
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "common/result.hpp"

namespace pitmap::acq {

// Values match raw_bytes_t.TRANSPORT_* (io does not depend on the LCM types).
enum class Transport : std::int8_t { kSerial = 1, kTcp = 2, kUdp = 3, kFile = 4 };

enum class SourceState : std::int8_t {
    kClosed = 0,        // never opened, or Close() was called
    kConnecting = 1,    // an open/connect attempt is in progress
    kOpen = 2,          // delivering bytes
    kDisconnected = 3,  // lost or failed to open; Read() retries with backoff
    kFinished = 4,      // a file source reached its end
};
const char* ToString(SourceState state);

// One chunk exactly as the transport delivered it: one read() on a tty or TCP socket, one
// UDP datagram, one block of a replayed file.
struct Chunk {
    std::vector<std::byte> data;    // the bytes, unmodified
    std::int64_t utime_host = 0;    // host receive time, Unix microseconds (CLOCK_REALTIME),
                                    // taken right after the read returned
    std::int64_t utime_kernel = 0;  // kernel receive timestamp (SO_TIMESTAMPNS), Unix
                                    // microseconds; 0 = not available
    std::string peer;               // "address:port" for UDP/TCP, device path for serial, ""
    bool truncated = false;         // UDP only: the datagram was longer than the buffer
    bool foreign = false;           // UDP only: the sender is not on the source's allow-list
                                    // (UdpConfig::allowed_senders); such bytes are evidence,
                                    // never sensor data
};

enum class ReadOutcome {
    kData,         // `chunk` holds at least one byte
    kTimeout,      // nothing within the timeout (also while waiting to reconnect)
    kEndOfStream,  // no more data will ever come (end of a replayed file)
};

class ByteSource {
public:
    virtual ~ByteSource() = default;
    ByteSource() = default;
    ByteSource(const ByteSource&) = delete;
    ByteSource& operator=(const ByteSource&) = delete;

    // Opens the device. On failure the source is kDisconnected and Read() keeps retrying
    // with backoff; the caller decides whether a failed first open is fatal.
    virtual Status Open() = 0;
    // Waits at most `timeout_ms` (>= 0) for data. An error means a transport failure (the
    // device went away, a reopen attempt failed); the source then reopens by itself on a
    // later Read(). `chunk` is overwritten on kData and left in an unspecified state otherwise.
    virtual Expected<ReadOutcome> Read(Chunk& chunk, int timeout_ms) = 0;
    // Writes all of `bytes` (receiver commands) within `timeout_ms`. Fails when closed.
    virtual Status Write(std::span<const std::byte> bytes, int timeout_ms) = 0;
    // Releases the device; idempotent. A later Open() starts again.
    virtual void Close() = 0;

    virtual Transport transport() const = 0;
    // Human description for logs, e.g. "serial /dev/ttyUSB0 460800 8N1".
    virtual std::string description() const = 0;

    SourceState state() const { return state_.load(std::memory_order_relaxed); }
    // Successful reopens after a loss (the first open does not count).
    std::int64_t reconnects() const { return reconnects_.load(std::memory_order_relaxed); }
    // +1 on every successful open: a channel that sees it change re-sends its set-up commands.
    std::int64_t generation() const { return generation_.load(std::memory_order_relaxed); }
    // Datagrams the kernel dropped on this source's socket before they were read (receive
    // buffer full), summed over reopens. Always 0 for transports that cannot lose data in the
    // kernel without the reader seeing it (serial, TCP, files).
    std::int64_t kernel_drops() const { return kernel_drops_.load(std::memory_order_relaxed); }
    // The last transport error message, "" if none. Owner thread only.
    const std::string& last_error() const { return last_error_; }

protected:
    void set_state(SourceState s) { state_.store(s, std::memory_order_relaxed); }
    void NoteOpened() {
        if (generation_.fetch_add(1, std::memory_order_relaxed) > 0) {
            reconnects_.fetch_add(1, std::memory_order_relaxed);
        }
        set_state(SourceState::kOpen);
    }
    void AddKernelDrops(std::int64_t n) { kernel_drops_.fetch_add(n, std::memory_order_relaxed); }
    Error Fail(std::string message) {
        last_error_ = message;
        return Error{std::move(message)};
    }

private:
    std::atomic<SourceState> state_{SourceState::kClosed};
    std::atomic<std::int64_t> reconnects_{0};
    std::atomic<std::int64_t> generation_{0};
    std::atomic<std::int64_t> kernel_drops_{0};
    std::string last_error_;
};

// Host clock, Unix microseconds (CLOCK_REALTIME). io/ is allowed to read clocks.
std::int64_t HostNowUtime();
// Monotonic clock in microseconds, for timeouts and backoff.
std::int64_t MonotonicNowUs();

}  // namespace pitmap::acq
