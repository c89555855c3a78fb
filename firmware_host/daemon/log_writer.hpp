// SPDX-License-Identifier: MIT
// LogWriter: writes LCM log files, byte-compatible with lcm-logger and lcm::LogFile.
//
// Event layout (LCM eventlog, all integers big-endian):
//   uint32 sync 0xEDA1DA01 | int64 event number | int64 timestamp (us) |
//   int32 channel length | int32 data length | channel bytes | data bytes
// Event numbers start at 0 in every file, as lcm::LogFile writes them.
//
// The channels' reader threads call Enqueue(), which never blocks on disk: a bounded queue
// (events and bytes) feeds one writer thread, and a full queue drops the event and counts it
// (as lcm-logger does). Every event is handed to the kernel with write(2) as soon as the
// writer takes it, so a `kill -9` of the daemon loses only what was still queued and at most
// a truncated last event; fdatasync runs every flush_interval_ms so a power cut loses at most
// that much. Files rotate by size and by age (names `<prefix>-YYYYmmdd-HHMMSS-NNN.lcmlog`,
// UTC at opening, NNN counting files of this writer). A free-space guard (statvfs) closes the
// file cleanly when free space drops below min_free_bytes, keeps counting dropped events and
// opens a new file once space is back above min_free_bytes + resume_margin_bytes. A write
// error (ENOSPC, EIO, EFBIG) truncates the file back to the last complete event, closes it,
// is counted and reported, and writing is retried after error_retry_ms; nothing is fatal.
// A segment that holds no complete event when it is closed or abandoned (its first write
// failed) is removed, so no 0-byte log is ever left behind. Files are created 0640.
//
// A vanished log (issue 14): on every flush interval and before a file is closed, the open
// segment is checked with fstat (st_nlink 0: deleted) and its directory by comparing the
// path's stat with the directory the segment was opened in (deleted, replaced, unmounted).
// Either is reported (a rate-limited human line, LogWriterStats::directory_lost, and the
// events of a deleted segment in events_lost), the segment is closed and the next event opens
// a new one: the directory is created again (mkdir -p) or, when that or the file creation
// fails, the optional fallback_directory is used. Each new file tries the primary first.
//
// THREADING: Enqueue(), RequestRotate(), Flush() and stats() may be called from any thread.
// Start()/Stop() from one controlling thread (idempotent). The writer thread owns the file
// descriptor and all file state; the queue is guarded by queue_mu_, the statistics by
// stats_mu_. A syncer thread runs the periodic fdatasync on a dup of the descriptor
// (sync_mu_).
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "common/result.hpp"
#include "firmware_host/daemon/rate_limited_log.hpp"

namespace pitmap::acq {

struct LogWriterConfig {
    std::string directory;                          // existing directory for the log files
    std::string fallback_directory{};               // used when `directory` fails; "" = none
    std::string prefix = "pitmap";                  // file name prefix
    std::size_t queue_max_events = 100'000;         // queued events before dropping
    std::size_t queue_max_bytes = 64u << 20;        // queued payload bytes before dropping
    std::int64_t rotate_bytes = 1LL << 30;          // start a new file beyond this size; 0 = never
    std::int64_t rotate_interval_s = 3600;          // start a new file after this long; 0 = never
    int flush_interval_ms = 500;                    // fdatasync period, milliseconds
    std::int64_t min_free_bytes = 512LL << 20;      // disk guard: stop below this; 0 = no guard
    std::int64_t resume_margin_bytes = 64LL << 20;  // resume at min_free + this
    int disk_check_interval_ms = 1000;              // statvfs period, milliseconds
    int error_retry_ms = 5000;                      // after a write error, retry after this long

    std::vector<std::string> Validate() const;
};

// Values match daemon_status_t.LOGGING_*.
enum class LogWriterState : std::int8_t { kOff = 0, kOn = 1, kDiskGuard = 2, kError = 3 };

struct LogWriterStats {
    LogWriterState state = LogWriterState::kOff;
    std::string current_path;              // "" when no file is open
    std::int64_t bytes_written = 0;        // bytes of complete events written, all files
    std::int64_t events_written = 0;       // complete events written, all files
    std::int64_t dropped_queue_full = 0;   // Enqueue() refused: queue full or not running
    std::int64_t dropped_disk_guard = 0;   // taken from the queue while the guard was on
    std::int64_t dropped_write_error = 0;  // lost to a write error or while waiting to retry
    std::int64_t write_errors = 0;         // failed writes/opens
    std::int64_t files_opened = 0;
    std::int64_t directory_lost = 0;    // open segment or its directory vanished (deleted,
                                        // replaced, unmounted) and a new one was started
    std::int64_t events_lost = 0;       // events written to segments deleted while open
    std::string directory;              // directory of the current (last) file; "" before any
    std::int64_t disk_free_bytes = -1;  // last statvfs result; -1 = unknown
    std::string last_error;             // "" if none
    std::int64_t dropped() const {
        return dropped_queue_full + dropped_disk_guard + dropped_write_error;
    }
};

// Seams for tests: the wall clock (file names, time rotation) and the free-space probe.
struct LogWriterHooks {
    std::function<std::int64_t()> now_utime{};  // Unix us; default CLOCK_REALTIME
    std::function<std::optional<std::int64_t>(const std::string& directory)> free_bytes{};
    // default statvfs; nullopt = unknown
};

// One encoded LCM log event (see the layout above).
std::vector<std::byte> EncodeLcmLogEvent(std::int64_t event_number,
                                         std::int64_t utime,
                                         std::string_view channel,
                                         std::span<const std::uint8_t> data);
// "<prefix>-YYYYmmdd-HHMMSS-NNN.lcmlog" for a UTC Unix time.
std::string LogFileName(const std::string& prefix, std::int64_t utime, int sequence);

class LogWriter {
public:
    // Precondition: config.Validate() is empty. `human_log` (may be null, must outlive this)
    // gets the rate-limited lines about a vanished directory and failing file creation.
    explicit LogWriter(LogWriterConfig config,
                       LogWriterHooks hooks = {},
                       RateLimitedLog* human_log = nullptr);
    ~LogWriter();
    LogWriter(const LogWriter&) = delete;
    LogWriter& operator=(const LogWriter&) = delete;

    // Starts the writer thread (the first file opens with the first event). Fails when the
    // directory is missing or not writable and no fallback_directory can be created and
    // written. Idempotent.
    Status Start();
    // Writes everything queued, syncs, closes. Idempotent.
    void Stop();

    // Queues one event; never blocks on I/O. False when it was dropped (queue full), counted.
    // Events queued before Start() are written once the thread runs.
    bool Enqueue(std::int64_t utime, std::string channel, std::vector<std::uint8_t> data);
    // Closes the current file; the next event opens a new one (SIGHUP).
    void RequestRotate();
    // Waits until everything queued so far is written and synced (bounded by timeout_ms);
    // false on timeout or when not running.
    bool Flush(int timeout_ms);

    LogWriterStats stats() const;

private:
    struct Event {
        std::int64_t utime;
        std::string channel;
        std::vector<std::uint8_t> data;
    };

    void Run();
    void WriteOne(const Event& e);
    bool OpenNewFile();
    // Creates `dir` if missing and a new segment in it; on failure `error` says why.
    bool OpenIn(const std::string& dir, std::string& error);
    void CloseFile();
    // Closes the open segment (syncing it first when `sync`), removing it when it holds no
    // complete event and `remove_if_empty`.
    void ReleaseSegment(bool sync, bool remove_if_empty);
    // Writer thread: when the open segment or its directory vanished, reports it, counts it
    // and closes the segment (the next event opens a new one). True if it did.
    bool CheckSegmentGone();
    void Say(const std::string& key, const std::string& message);
    void Sync();
    // The periodic fdatasync runs on its own thread, on a dup of the file descriptor, so a slow
    // sync (eMMC, a busy disk) never holds up writing the events behind it. Flush() and Stop()
    // still sync synchronously, after any sync in flight.
    void SyncLoop();
    bool StartAsyncSync();     // writer thread: hand the file to the syncer; false if it is busy
    void WaitAsyncSyncIdle();  // writer thread: wait until no sync is in flight
    void CheckDisk(bool force);
    void SetError(const std::string& message);
    std::int64_t Now() const;

    const LogWriterConfig config_;
    LogWriterHooks hooks_;
    RateLimitedLog* human_log_;

    mutable std::mutex queue_mu_;
    std::condition_variable queue_cv_;
    std::condition_variable flushed_cv_;
    std::deque<Event> queue_;
    std::size_t queue_bytes_ = 0;
    bool stop_requested_ = false;
    bool rotate_requested_ = false;
    std::uint64_t flush_requested_ = 0;  // generation asked for
    std::uint64_t flush_done_ = 0;       // generation completed
    std::thread thread_;
    std::thread sync_thread_;
    std::mutex sync_mu_;  // guards the four fields below
    std::condition_variable sync_cv_;
    int sync_fd_ = -1;  // dup of the log fd handed to the syncer
    bool sync_busy_ = false;
    bool sync_stop_ = false;
    std::string sync_path_;
    bool running_ = false;  // controlling thread only

    mutable std::mutex stats_mu_;
    LogWriterStats stats_;

    // Writer thread only.
    int fd_ = -1;
    int dir_fd_ = -1;   // the directory the open segment was created in
    std::string dir_;   // its path (config directory or fallback)
    std::string name_;  // the segment's file name in dir_
    std::string path_;
    std::string last_dir_;  // directory of the previous segment, "" before the first
    std::int64_t last_gone_check_us_ = 0;
    std::int64_t file_bytes_ = 0;
    std::int64_t file_open_utime_ = 0;
    std::int64_t event_number_ = 0;
    int file_sequence_ = 0;
    bool dirty_ = false;
    std::int64_t last_sync_us_ = 0;
    std::int64_t last_disk_check_us_ = 0;
    std::int64_t retry_at_us_ = 0;
    std::vector<std::byte> buffer_;
};

}  // namespace pitmap::acq
