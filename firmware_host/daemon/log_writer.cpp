// SPDX-License-Identifier: MIT
#include "firmware_host/daemon/log_writer.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <utility>

#include "common/gps_time.hpp"
#include "firmware_host/io/byte_source.hpp"

namespace pitmap::acq {
namespace {

constexpr std::uint32_t kLcmSyncWord = 0xEDA1DA01u;

void PutBe(std::vector<std::byte>& out, std::uint64_t v, int bytes) {
    for (int i = bytes - 1; i >= 0; --i)
        out.push_back(static_cast<std::byte>((v >> (8 * i)) & 0xFF));
}

std::string Errno(const std::string& what, int err) {
    return what + ": " + std::strerror(err) + " (errno " + std::to_string(err) + ")";
}

std::optional<std::int64_t> StatvfsFree(const std::string& dir) {
    struct statvfs s {};
    if (::statvfs(dir.c_str(), &s) != 0) return std::nullopt;
    return static_cast<std::int64_t>(s.f_bavail) * static_cast<std::int64_t>(s.f_frsize);
}

}  // namespace

std::vector<std::byte> EncodeLcmLogEvent(std::int64_t event_number,
                                         std::int64_t utime,
                                         std::string_view channel,
                                         std::span<const std::uint8_t> data) {
    std::vector<std::byte> out;
    out.reserve(28 + channel.size() + data.size());
    PutBe(out, kLcmSyncWord, 4);
    PutBe(out, static_cast<std::uint64_t>(event_number), 8);
    PutBe(out, static_cast<std::uint64_t>(utime), 8);
    PutBe(out, static_cast<std::uint32_t>(channel.size()), 4);
    PutBe(out, static_cast<std::uint32_t>(data.size()), 4);
    for (char c : channel) out.push_back(static_cast<std::byte>(c));
    for (std::uint8_t b : data) out.push_back(static_cast<std::byte>(b));
    return out;
}

std::string LogFileName(const std::string& prefix, std::int64_t utime, int sequence) {
    const UtcCalendar c = UtcCalendarFromUnix(utime);
    char buf[64];
    std::snprintf(buf,
                  sizeof(buf),
                  "-%04d%02d%02d-%02d%02d%02d-%03d.lcmlog",
                  c.year,
                  c.month,
                  c.day,
                  c.hour,
                  c.minute,
                  c.second,
                  sequence % 1000);
    return prefix + buf;
}

std::vector<std::string> LogWriterConfig::Validate() const {
    std::vector<std::string> p;
    if (directory.empty()) p.push_back("log: directory is empty");
    if (prefix.empty() || prefix.find('/') != std::string::npos) {
        p.push_back("log: prefix must be a non-empty file name part without '/'");
    }
    if (queue_max_events == 0) p.push_back("log: queue_max_events must be > 0");
    if (queue_max_bytes == 0) p.push_back("log: queue_max_bytes must be > 0");
    if (rotate_bytes < 0) p.push_back("log: rotate_bytes must be >= 0");
    if (rotate_interval_s < 0) p.push_back("log: rotate_interval_s must be >= 0");
    if (flush_interval_ms <= 0) p.push_back("log: flush_interval_ms must be > 0");
    if (min_free_bytes < 0 || resume_margin_bytes < 0) {
        p.push_back("log: min_free_bytes and resume_margin_bytes must be >= 0");
    }
    if (disk_check_interval_ms <= 0) p.push_back("log: disk_check_interval_ms must be > 0");
    if (error_retry_ms <= 0) p.push_back("log: error_retry_ms must be > 0");
    if (!fallback_directory.empty() && fallback_directory == directory) {
        p.push_back("log: fallback_dir must differ from directory");
    }
    return p;
}

LogWriter::LogWriter(LogWriterConfig config, LogWriterHooks hooks, RateLimitedLog* human_log)
    : config_(std::move(config)), hooks_(std::move(hooks)), human_log_(human_log) {
    PITMAP_CHECK(config_.Validate().empty(), "LogWriter: invalid config");
    if (!hooks_.now_utime) hooks_.now_utime = [] { return HostNowUtime(); };
    if (!hooks_.free_bytes) hooks_.free_bytes = StatvfsFree;
}

LogWriter::~LogWriter() {
    Stop();
}

std::int64_t LogWriter::Now() const {
    return hooks_.now_utime();
}

Status LogWriter::Start() {
    if (running_) return Ok{};
    struct stat st {};
    std::string problem;
    if (::stat(config_.directory.c_str(), &st) != 0 || !S_ISDIR(st.st_mode)) {
        problem = "log: directory " + config_.directory + " does not exist";
    } else if (::access(config_.directory.c_str(), W_OK) != 0) {
        problem = Errno("log: directory " + config_.directory + " is not writable", errno);
    }
    if (!problem.empty()) {
        if (config_.fallback_directory.empty()) return Error{problem};
        std::error_code ec;
        std::filesystem::create_directories(config_.fallback_directory, ec);
        if (ec || ::access(config_.fallback_directory.c_str(), W_OK) != 0) {
            return Error{problem + "; fallback directory " + config_.fallback_directory +
                         " is not usable either"};
        }
        Say("log:directory",
            problem + "; logging to fallback directory " + config_.fallback_directory);
    }
    {
        std::lock_guard lock(queue_mu_);
        stop_requested_ = false;
    }
    {
        std::lock_guard lock(stats_mu_);
        stats_.state = LogWriterState::kOn;
    }
    last_disk_check_us_ = 0;
    running_ = true;
    {
        std::lock_guard lock(sync_mu_);
        sync_stop_ = false;
    }
    sync_thread_ = std::thread([this] { SyncLoop(); });
    thread_ = std::thread([this] { Run(); });
    return Ok{};
}

void LogWriter::Stop() {
    if (!running_) return;
    {
        std::lock_guard lock(queue_mu_);
        stop_requested_ = true;
    }
    queue_cv_.notify_all();
    thread_.join();
    {
        std::lock_guard lock(sync_mu_);
        sync_stop_ = true;
    }
    sync_cv_.notify_all();
    sync_thread_.join();
    running_ = false;
    std::lock_guard lock(stats_mu_);
    stats_.state = LogWriterState::kOff;
}

bool LogWriter::Enqueue(std::int64_t utime, std::string channel, std::vector<std::uint8_t> data) {
    const std::size_t size = data.size() + channel.size();
    {
        std::lock_guard lock(queue_mu_);
        if (queue_.size() < config_.queue_max_events &&
            queue_bytes_ + size <= config_.queue_max_bytes) {
            queue_bytes_ += size;
            queue_.push_back(Event{utime, std::move(channel), std::move(data)});
            queue_cv_.notify_one();
            return true;
        }
    }
    std::lock_guard lock(stats_mu_);
    ++stats_.dropped_queue_full;
    return false;
}

void LogWriter::RequestRotate() {
    std::lock_guard lock(queue_mu_);
    rotate_requested_ = true;
    queue_cv_.notify_one();
}

bool LogWriter::Flush(int timeout_ms) {
    std::unique_lock lock(queue_mu_);
    if (!running_ || stop_requested_) return false;
    const std::uint64_t want = ++flush_requested_;
    queue_cv_.notify_one();
    return flushed_cv_.wait_for(
        lock, std::chrono::milliseconds(timeout_ms), [&] { return flush_done_ >= want; });
}

LogWriterStats LogWriter::stats() const {
    std::lock_guard lock(stats_mu_);
    return stats_;
}

void LogWriter::Run() {
    std::deque<Event> batch;
    for (;;) {
        bool stop = false;
        bool rotate = false;
        std::uint64_t flush_gen = 0;
        {
            std::unique_lock lock(queue_mu_);
            queue_cv_.wait_for(lock, std::chrono::milliseconds(config_.flush_interval_ms), [&] {
                return !queue_.empty() || stop_requested_ || rotate_requested_ ||
                       flush_requested_ > flush_done_;
            });
            batch.swap(queue_);
            queue_bytes_ = 0;
            stop = stop_requested_;
            rotate = rotate_requested_;
            rotate_requested_ = false;
            flush_gen = flush_requested_;
        }
        const std::int64_t pass_mono = MonotonicNowUs();
        if (fd_ >= 0 && pass_mono - last_gone_check_us_ >= config_.flush_interval_ms * 1000LL) {
            last_gone_check_us_ = pass_mono;
            CheckSegmentGone();
        }
        if (rotate) CloseFile();
        if (!batch.empty()) CheckDisk(false);
        for (const Event& e : batch) WriteOne(e);
        batch.clear();
        const std::int64_t mono = MonotonicNowUs();
        if (dirty_) {
            if (stop || flush_gen > 0) {
                // Flush() and Stop() promise synced data: wait for a sync in flight, then sync.
                WaitAsyncSyncIdle();
                Sync();
            } else if (mono - last_sync_us_ >= config_.flush_interval_ms * 1000LL &&
                       StartAsyncSync()) {
                dirty_ = false;
                last_sync_us_ = mono;
            }
        }
        CheckDisk(false);
        {
            std::lock_guard lock(queue_mu_);
            if (flush_gen > flush_done_) flush_done_ = flush_gen;
        }
        flushed_cv_.notify_all();
        if (stop) {
            std::lock_guard lock(queue_mu_);
            if (queue_.empty()) break;
        }
    }
    CloseFile();
}

void LogWriter::Say(const std::string& key, const std::string& message) {
    if (human_log_ != nullptr) human_log_->Log(key, MonotonicNowUs(), message);
}

void LogWriter::SetError(const std::string& message) {
    std::lock_guard lock(stats_mu_);
    ++stats_.write_errors;
    stats_.last_error = message;
    stats_.state = LogWriterState::kError;
    retry_at_us_ = MonotonicNowUs() + config_.error_retry_ms * 1000LL;
}

void LogWriter::CheckDisk(bool force) {
    if (config_.min_free_bytes == 0) return;
    const std::int64_t mono = MonotonicNowUs();
    if (!force && last_disk_check_us_ != 0 &&
        mono - last_disk_check_us_ < config_.disk_check_interval_ms * 1000LL) {
        return;
    }
    last_disk_check_us_ = mono;
    const std::optional<std::int64_t> free =
        hooks_.free_bytes(last_dir_.empty() ? config_.directory : last_dir_);
    LogWriterState state;
    {
        std::lock_guard lock(stats_mu_);
        stats_.disk_free_bytes = free.value_or(-1);
        state = stats_.state;
    }
    if (!free) return;
    if (state == LogWriterState::kOn && *free < config_.min_free_bytes) {
        CloseFile();
        std::lock_guard lock(stats_mu_);
        stats_.state = LogWriterState::kDiskGuard;
        stats_.last_error = "disk guard: " + std::to_string(*free) + " bytes free < " +
                            std::to_string(config_.min_free_bytes);
    } else if (state == LogWriterState::kDiskGuard &&
               *free >= config_.min_free_bytes + config_.resume_margin_bytes) {
        std::lock_guard lock(stats_mu_);
        stats_.state = LogWriterState::kOn;
    }
}

bool LogWriter::OpenNewFile() {
    std::string error;
    if (OpenIn(config_.directory, error)) {
        if (!last_dir_.empty() && last_dir_ != config_.directory) {
            Say("log:directory", "log: writing to " + config_.directory + " again");
        }
        last_dir_ = config_.directory;
        return true;
    }
    if (!config_.fallback_directory.empty()) {
        std::string fallback_error;
        if (OpenIn(config_.fallback_directory, fallback_error)) {
            if (last_dir_ != config_.fallback_directory) {
                Say("log:directory",
                    error + "; writing to fallback directory " + config_.fallback_directory);
            }
            last_dir_ = config_.fallback_directory;
            return true;
        }
        error += "; fallback: " + fallback_error;
    }
    SetError(error);
    Say("log:open", error + "; retrying in " + std::to_string(config_.error_retry_ms) + " ms");
    return false;
}

bool LogWriter::OpenIn(const std::string& dir, std::string& error) {
    struct stat st {};
    if (::stat(dir.c_str(), &st) != 0) {
        // Missing (deleted, or its file system went away): make it again.
        std::error_code ec;
        std::filesystem::create_directories(dir, ec);
        if (ec) {
            error = "log: cannot create directory " + dir + ": " + ec.message();
            return false;
        }
        if (!last_dir_.empty()) {
            Say("log:recreated", "log: directory " + dir + " was missing: created it again");
        }
    }
    const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (dfd < 0) {
        error = Errno("log: open directory " + dir, errno);
        return false;
    }
    const std::int64_t now = Now();
    for (int attempt = 0; attempt < 1000; ++attempt) {
        const std::string name = LogFileName(config_.prefix, now, file_sequence_++);
        // 0640: the logs are readable by the daemon's group, not by everyone (the umask of the
        // systemd unit, 0027, agrees).
        const int fd = ::openat(dfd, name.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0640);
        if (fd < 0 && errno == EEXIST) continue;
        if (fd < 0) {
            error = Errno("log: create " + dir + "/" + name, errno);
            ::close(dfd);
            return false;
        }
        // Make the new directory entry durable too, or a power cut can lose the whole file.
        ::fsync(dfd);
        fd_ = fd;
        dir_fd_ = dfd;
        dir_ = dir;
        name_ = name;
        path_ = dir + "/" + name;
        file_bytes_ = 0;
        file_open_utime_ = now;
        event_number_ = 0;
        dirty_ = false;
        last_sync_us_ = MonotonicNowUs();
        last_gone_check_us_ = last_sync_us_;
        std::lock_guard lock(stats_mu_);
        ++stats_.files_opened;
        stats_.current_path = path_;
        stats_.directory = dir;
        return true;
    }
    ::close(dfd);
    error = "log: no free file name for prefix " + config_.prefix + " in " + dir;
    return false;
}

bool LogWriter::CheckSegmentGone() {
    if (fd_ < 0) return false;
    struct stat file_st {};
    struct stat dir_st {};
    struct stat path_st {};
    const bool deleted = ::fstat(fd_, &file_st) == 0 && file_st.st_nlink == 0;
    std::string what;
    if (deleted) {
        what = "log: file " + path_ + " was deleted while open";
    } else if (::fstat(dir_fd_, &dir_st) == 0) {
        if (::stat(dir_.c_str(), &path_st) != 0) {
            what = Errno("log: directory " + dir_ + " is gone", errno);
        } else if (path_st.st_dev != dir_st.st_dev || path_st.st_ino != dir_st.st_ino) {
            what = "log: directory " + dir_ + " was replaced or unmounted under " + path_;
        }
    }
    if (what.empty()) return false;
    const std::int64_t lost = deleted ? event_number_ : 0;
    if (deleted) what += " (its " + std::to_string(lost) + " events are lost)";
    what += "; starting a new file";
    {
        std::lock_guard lock(stats_mu_);
        ++stats_.directory_lost;
        stats_.events_lost += lost;
        stats_.last_error = what;
    }
    Say("log:gone", what);
    if (deleted) dirty_ = false;  // nothing to keep: no sync, and nothing to remove
    ReleaseSegment(/*sync=*/!deleted, /*remove_if_empty=*/!deleted);
    return true;
}

bool LogWriter::StartAsyncSync() {
    if (fd_ < 0) return false;
    std::lock_guard lock(sync_mu_);
    if (sync_busy_) return false;  // the previous sync is still running: try at the next pass
    const int d = ::dup(fd_);
    if (d < 0) return false;
    sync_fd_ = d;
    sync_path_ = path_;
    sync_busy_ = true;
    sync_cv_.notify_all();
    return true;
}

void LogWriter::WaitAsyncSyncIdle() {
    std::unique_lock lock(sync_mu_);
    sync_cv_.wait(lock, [&] { return !sync_busy_; });
}

void LogWriter::SyncLoop() {
    std::unique_lock lock(sync_mu_);
    for (;;) {
        sync_cv_.wait(lock, [&] { return sync_busy_ || sync_stop_; });
        if (!sync_busy_) break;  // stop requested and nothing in flight
        const int fd = sync_fd_;
        const std::string path = sync_path_;
        lock.unlock();
        const int rc = ::fdatasync(fd);
        const int err = errno;
        ::close(fd);
        if (rc != 0) {
            // Counted and reported; the writer's own write errors drive the retry logic.
            std::lock_guard stats_lock(stats_mu_);
            ++stats_.write_errors;
            stats_.last_error = Errno("log: fdatasync " + path, err);
        }
        lock.lock();
        sync_fd_ = -1;
        sync_busy_ = false;
        sync_cv_.notify_all();
    }
}

void LogWriter::Sync() {
    if (fd_ < 0) return;
    if (::fdatasync(fd_) != 0) SetError(Errno("log: fdatasync " + path_, errno));
    dirty_ = false;
    last_sync_us_ = MonotonicNowUs();
}

void LogWriter::CloseFile() {
    if (fd_ < 0) return;
    if (CheckSegmentGone()) return;  // reported and already released
    ReleaseSegment(/*sync=*/true, /*remove_if_empty=*/true);
}

void LogWriter::ReleaseSegment(bool sync, bool remove_if_empty) {
    if (fd_ < 0) return;
    if (sync && dirty_) Sync();
    ::close(fd_);
    fd_ = -1;
    // A segment without one complete event (its first write failed, or nothing came) is no
    // log: remove it rather than leave a 0-byte file for the shore tools.
    if (remove_if_empty && file_bytes_ == 0) ::unlinkat(dir_fd_, name_.c_str(), 0);
    ::close(dir_fd_);
    dir_fd_ = -1;
    path_.clear();
    name_.clear();
    dir_.clear();
    dirty_ = false;
    std::lock_guard lock(stats_mu_);
    stats_.current_path.clear();
}

void LogWriter::WriteOne(const Event& e) {
    LogWriterState state;
    {
        std::lock_guard lock(stats_mu_);
        state = stats_.state;
    }
    if (state == LogWriterState::kDiskGuard) {
        CheckDisk(false);
        std::lock_guard lock(stats_mu_);
        if (stats_.state == LogWriterState::kDiskGuard) {
            ++stats_.dropped_disk_guard;
            return;
        }
    }
    if (state == LogWriterState::kError) {
        if (MonotonicNowUs() < retry_at_us_) {
            std::lock_guard lock(stats_mu_);
            ++stats_.dropped_write_error;
            return;
        }
        {
            std::lock_guard lock(stats_mu_);
            stats_.state = LogWriterState::kOn;
        }
        CheckDisk(true);
        std::lock_guard lock(stats_mu_);
        if (stats_.state != LogWriterState::kOn) {
            ++stats_.dropped_disk_guard;
            return;
        }
    }
    const std::int64_t size = 28 + static_cast<std::int64_t>(e.channel.size() + e.data.size());
    if (fd_ >= 0) {
        const bool too_big = config_.rotate_bytes > 0 && file_bytes_ > 0 &&
                             file_bytes_ + size > config_.rotate_bytes;
        const bool too_old = config_.rotate_interval_s > 0 &&
                             Now() - file_open_utime_ >= config_.rotate_interval_s * 1'000'000;
        if (too_big || too_old) CloseFile();
    }
    if (fd_ < 0 && !OpenNewFile()) {
        std::lock_guard lock(stats_mu_);
        ++stats_.dropped_write_error;
        return;
    }
    buffer_ = EncodeLcmLogEvent(event_number_, e.utime, e.channel, e.data);
    std::size_t done = 0;
    while (done < buffer_.size()) {
        const ssize_t n = ::write(fd_, buffer_.data() + done, buffer_.size() - done);
        if (n > 0) {
            done += static_cast<std::size_t>(n);
            continue;
        }
        if (n < 0 && errno == EINTR) continue;
        const int err = n < 0 ? errno : EIO;
        // Cut the partial event off so the file ends on a complete event and a later writer
        // (or lcm::LogFile) never sees half an event followed by more data.
        const std::string path = path_;
        const bool truncated = ::ftruncate(fd_, file_bytes_) == 0 &&
                               ::lseek(fd_, file_bytes_, SEEK_SET) == file_bytes_;
        // As before this change: the complete events before are not synced here (the disk is
        // failing); an empty segment is removed.
        dirty_ = false;
        ReleaseSegment(/*sync=*/false, /*remove_if_empty=*/true);
        SetError(Errno("log: write " + path, err) +
                 (truncated ? "" : " (and the partial event could not be cut off)"));
        std::lock_guard lock(stats_mu_);
        ++stats_.dropped_write_error;
        stats_.current_path.clear();
        return;
    }
    file_bytes_ += size;
    ++event_number_;
    dirty_ = true;
    std::lock_guard lock(stats_mu_);
    ++stats_.events_written;
    stats_.bytes_written += size;
}

}  // namespace pitmap::acq
