// SPDX-License-Identifier: MIT
// LogWriter against lcm::LogFile: byte format, rotation, drops, kill -9, full disk, a log
// directory deleted under the writer (issue 14), file modes.
#include "firmware_host/daemon/log_writer.hpp"
#include "firmware_host/daemon/rate_limited_log.hpp"
#include "tests/support/work_dir.hpp"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <sched.h>
#include <signal.h>
#include <sys/mount.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <lcm/lcm-cpp.hpp>
#include <regex>
#include <string>
#include <thread>
#include <vector>

namespace pitmap::acq {
namespace {

namespace fs = std::filesystem;

struct ReadEvent {
    std::int64_t eventnum;
    std::int64_t timestamp;
    std::string channel;
    std::vector<std::uint8_t> data;
};

std::vector<ReadEvent> ReadLog(const std::string& path) {
    std::vector<ReadEvent> out;
    lcm::LogFile log(path, "r");
    if (!log.good()) return out;
    while (const lcm::LogEvent* e = log.readNextEvent()) {
        const auto* p = static_cast<const std::uint8_t*>(e->data);
        out.push_back(
            {e->eventnum, e->timestamp, e->channel, std::vector<std::uint8_t>(p, p + e->datalen)});
    }
    return out;
}

std::vector<std::string> LogFiles(const std::string& dir) {
    std::vector<std::string> v;
    for (const auto& entry : fs::directory_iterator(dir)) v.push_back(entry.path().string());
    std::sort(v.begin(), v.end());
    return v;
}

std::string FreshDir(const std::string& name) {
    return pitmap::test::MakeWorkDir(::testing::TempDir() + "log_writer_" + name + "_" +
                                     std::to_string(::getpid()))
        .string();
}

std::vector<std::uint8_t> Payload(int i, std::size_t size) {
    std::vector<std::uint8_t> v(size);
    for (std::size_t k = 0; k < size; ++k) v[k] = static_cast<std::uint8_t>((i * 31 + k) & 0xFF);
    return v;
}

LogWriterConfig BaseConfig(const std::string& dir) {
    LogWriterConfig c;
    c.directory = dir;
    c.prefix = "test";
    c.min_free_bytes = 0;
    c.flush_interval_ms = 50;
    return c;
}

TEST(LogWriterTest, EncodingMatchesLcmLogFileByteForByte) {
    const std::string dir = FreshDir("bytes");
    const std::string ref = dir + "/ref.lcmlog";
    std::vector<std::byte> ours;
    {
        lcm::LogFile log(ref, "w");
        ASSERT_TRUE(log.good());
        for (int i = 0; i < 20; ++i) {
            std::vector<std::uint8_t> data = Payload(i, static_cast<std::size_t>(i * 7));
            const std::string channel = "RAW_NOVATEL_COM" + std::to_string(i % 3);
            lcm::LogEvent e{};
            e.eventnum = 0;  // LogFile numbers the events itself
            e.timestamp = 1'700'000'000'000'000 + i;
            e.channel = channel;
            e.datalen = static_cast<std::int32_t>(data.size());
            e.data = data.data();
            ASSERT_EQ(log.writeEvent(&e), 0);
            const auto enc = EncodeLcmLogEvent(i, e.timestamp, channel, data);
            ours.insert(ours.end(), enc.begin(), enc.end());
        }
    }
    std::ifstream f(ref, std::ios::binary);
    std::vector<char> theirs((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
    ASSERT_EQ(theirs.size(), ours.size());
    EXPECT_EQ(std::memcmp(theirs.data(), ours.data(), ours.size()), 0);
}

TEST(LogWriterTest, RoundTripThroughLcmLogFile) {
    const std::string dir = FreshDir("roundtrip");
    LogWriter w(BaseConfig(dir));
    ASSERT_TRUE(w.Start().ok());
    for (int i = 0; i < 500; ++i) {
        ASSERT_TRUE(w.Enqueue(
            1000 + i, "CH" + std::to_string(i % 5), Payload(i, static_cast<std::size_t>(i % 300))));
    }
    ASSERT_TRUE(w.Flush(5000));
    w.Stop();
    const LogWriterStats s = w.stats();
    EXPECT_EQ(s.events_written, 500);
    EXPECT_EQ(s.dropped(), 0);
    EXPECT_EQ(s.files_opened, 1);
    const auto files = LogFiles(dir);
    ASSERT_EQ(files.size(), 1u);
    EXPECT_TRUE(std::regex_search(files[0], std::regex("/test-[0-9]{8}-[0-9]{6}-000\\.lcmlog$")));
    EXPECT_EQ(static_cast<std::int64_t>(fs::file_size(files[0])), s.bytes_written);
    const auto events = ReadLog(files[0]);
    ASSERT_EQ(events.size(), 500u);
    for (int i = 0; i < 500; ++i) {
        EXPECT_EQ(events[i].eventnum, i);
        EXPECT_EQ(events[i].timestamp, 1000 + i);
        EXPECT_EQ(events[i].channel, "CH" + std::to_string(i % 5));
        EXPECT_EQ(events[i].data, Payload(i, static_cast<std::size_t>(i % 300)));
    }
}

TEST(LogWriterTest, FileNameIsUtc) {
    // 2019-09-10T18:57:46Z
    EXPECT_EQ(LogFileName("acq", 1'568'141'866'123'456, 7), "acq-20190910-185746-007.lcmlog");
}

TEST(LogWriterTest, RotatesBySizeWithoutLosingEvents) {
    const std::string dir = FreshDir("rot_size");
    LogWriterConfig c = BaseConfig(dir);
    c.rotate_bytes = 10'000;
    LogWriter w(c);
    ASSERT_TRUE(w.Start().ok());
    for (int i = 0; i < 100; ++i)
        ASSERT_TRUE(w.Enqueue(i, "C", Payload(i, 971)));  // 28 + 1 + 971 = 1000 B
    w.Stop();
    const auto files = LogFiles(dir);
    ASSERT_EQ(files.size(), 10u);
    int next = 0;
    for (const auto& f : files) {
        EXPECT_LE(fs::file_size(f), 10'000u);
        const auto events = ReadLog(f);
        EXPECT_EQ(events.size(), 10u);
        for (std::size_t k = 0; k < events.size(); ++k) {
            EXPECT_EQ(events[k].eventnum, static_cast<std::int64_t>(k));  // per file
            EXPECT_EQ(events[k].timestamp, next++);
        }
    }
    EXPECT_EQ(next, 100);
}

TEST(LogWriterTest, RotatesByTimeAndOnRequest) {
    const std::string dir = FreshDir("rot_time");
    LogWriterConfig c = BaseConfig(dir);
    c.rotate_interval_s = 60;
    std::atomic<std::int64_t> now{1'568'141'866'000'000};
    LogWriter w(c, {.now_utime = [&] { return now.load(); }});
    ASSERT_TRUE(w.Start().ok());
    w.Enqueue(1, "A", Payload(1, 10));
    ASSERT_TRUE(w.Flush(5000));
    now += 30'000'000;
    w.Enqueue(2, "A", Payload(2, 10));
    ASSERT_TRUE(w.Flush(5000));
    now += 31'000'000;  // 61 s after the first file opened
    w.Enqueue(3, "A", Payload(3, 10));
    ASSERT_TRUE(w.Flush(5000));
    w.RequestRotate();  // SIGHUP
    w.Enqueue(4, "A", Payload(4, 10));
    w.Stop();
    const auto files = LogFiles(dir);
    ASSERT_EQ(files.size(), 3u);
    EXPECT_TRUE(files[0].ends_with("test-20190910-185746-000.lcmlog")) << files[0];
    EXPECT_TRUE(files[1].ends_with("test-20190910-185847-001.lcmlog")) << files[1];
    EXPECT_TRUE(files[2].ends_with("test-20190910-185847-002.lcmlog")) << files[2];
    EXPECT_EQ(ReadLog(files[0]).size(), 2u);
    EXPECT_EQ(ReadLog(files[1]).size(), 1u);
    EXPECT_EQ(ReadLog(files[2]).size(), 1u);
}

TEST(LogWriterTest, FullQueueDropsAndCounts) {
    const std::string dir = FreshDir("queue");
    LogWriterConfig c = BaseConfig(dir);
    c.queue_max_events = 10;
    LogWriter w(c);
    // Not started yet: nothing drains the queue, so exactly 10 fit.
    int accepted = 0;
    for (int i = 0; i < 100; ++i) accepted += w.Enqueue(i, "C", Payload(i, 8)) ? 1 : 0;
    EXPECT_EQ(accepted, 10);
    EXPECT_EQ(w.stats().dropped_queue_full, 90);
    // The byte limit counts too.
    c.queue_max_events = 1000;
    c.queue_max_bytes = 1000;
    LogWriter wb(c);
    EXPECT_TRUE(wb.Enqueue(0, "C", Payload(0, 900)));
    EXPECT_FALSE(wb.Enqueue(1, "C", Payload(1, 200)));
    EXPECT_EQ(wb.stats().dropped_queue_full, 1);
    ASSERT_TRUE(w.Start().ok());
    w.Stop();
    const auto files = LogFiles(dir);
    ASSERT_EQ(files.size(), 1u);
    const auto events = ReadLog(files[0]);
    ASSERT_EQ(events.size(), 10u);
    EXPECT_EQ(events.back().timestamp, 9);
}

TEST(LogWriterTest, DiskGuardStopsCleanlyAndResumes) {
    const std::string dir = FreshDir("guard");
    LogWriterConfig c = BaseConfig(dir);
    c.min_free_bytes = 1000;
    c.resume_margin_bytes = 500;
    c.disk_check_interval_ms = 1;
    std::atomic<std::int64_t> free_bytes{1'000'000};
    LogWriter w(c, {.free_bytes = [&](const std::string&) {
                    return std::optional<std::int64_t>(free_bytes.load());
                }});
    ASSERT_TRUE(w.Start().ok());
    for (int i = 0; i < 5; ++i) w.Enqueue(i, "C", Payload(i, 10));
    ASSERT_TRUE(w.Flush(5000));
    free_bytes = 900;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
    for (int i = 5; i < 10; ++i) w.Enqueue(i, "C", Payload(i, 10));
    ASSERT_TRUE(w.Flush(5000));
    LogWriterStats s = w.stats();
    EXPECT_EQ(s.state, LogWriterState::kDiskGuard);
    EXPECT_EQ(s.dropped_disk_guard, 5);
    EXPECT_EQ(s.current_path, "");
    EXPECT_EQ(s.disk_free_bytes, 900);
    free_bytes = 1200;  // above the guard but below guard + margin: still off
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
    w.Enqueue(10, "C", Payload(10, 10));
    ASSERT_TRUE(w.Flush(5000));
    EXPECT_EQ(w.stats().state, LogWriterState::kDiskGuard);
    free_bytes = 2000;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
    for (int i = 11; i < 15; ++i) w.Enqueue(i, "C", Payload(i, 10));
    ASSERT_TRUE(w.Flush(5000));
    w.Stop();
    s = w.stats();
    EXPECT_EQ(s.events_written, 9);
    EXPECT_EQ(s.dropped_disk_guard, 6);
    const auto files = LogFiles(dir);
    ASSERT_EQ(files.size(), 2u);
    EXPECT_EQ(ReadLog(files[0]).size(), 5u);
    EXPECT_EQ(ReadLog(files[1]).size(), 4u);
    EXPECT_EQ(ReadLog(files[1]).front().timestamp, 11);
}

// Checks a log written by a writer that died: every complete event readable, numbered from 0
// and carrying the expected payload; returns the count, or -1 on a mismatch.
int CheckDeadLog(const std::string& path, std::size_t payload) {
    const auto events = ReadLog(path);
    for (std::size_t i = 0; i < events.size(); ++i) {
        if (events[i].eventnum != static_cast<std::int64_t>(i) ||
            events[i].timestamp != static_cast<std::int64_t>(i) ||
            events[i].data != Payload(static_cast<int>(i), payload)) {
            return -1;
        }
    }
    const std::size_t event_size = 28 + 1 + payload;
    const std::size_t size = fs::file_size(path);
    // Only a truncated last event may follow the complete ones.
    if (size < events.size() * event_size || size - events.size() * event_size >= event_size) {
        return -1;
    }
    return static_cast<int>(events.size());
}

TEST(LogWriterTest, KillNineLeavesAReadableLog) {
    const std::string dir = FreshDir("kill9");
    constexpr std::size_t kPayload = 200'000;
    const pid_t child = ::fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
        LogWriterConfig c = BaseConfig(dir);
        c.queue_max_bytes = 256u << 20;
        LogWriter w(c);
        if (!w.Start().ok()) ::_exit(2);
        for (int i = 0;; ++i) {
            while (!w.Enqueue(i, "C", Payload(i, kPayload))) {
                std::this_thread::sleep_for(std::chrono::milliseconds(1));
            }
        }
    }
    // Wait until a few MB are on disk, then kill without warning.
    bool grown = false;
    for (int i = 0; i < 5000 && !grown; ++i) {
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
        for (const auto& entry : fs::directory_iterator(dir)) {
            std::error_code ec;
            if (fs::file_size(entry.path(), ec) > (4u << 20)) grown = true;
        }
    }
    ::kill(child, SIGKILL);
    int status = 0;
    ::waitpid(child, &status, 0);
    ASSERT_TRUE(grown);
    ASSERT_TRUE(WIFSIGNALED(status));
    const auto files = LogFiles(dir);
    ASSERT_EQ(files.size(), 1u);
    const int n = CheckDeadLog(files[0], kPayload);
    EXPECT_GE(n, 20);
    std::printf("kill -9: %d complete events readable, %ju bytes in the file\n",
                n,
                static_cast<std::uintmax_t>(fs::file_size(files[0])));
}

// Runs a writer in a child until a write error; the child checks the error was counted and
// the file ends on a complete event. Exit code 0 = good.
int WriteUntilErrorInChild(const std::string& dir, std::int64_t expect_max_size) {
    LogWriterConfig c = BaseConfig(dir);
    c.error_retry_ms = 60'000;
    LogWriter w(c);
    if (!w.Start().ok()) return 10;
    for (int i = 0; i < 2000; ++i) {
        w.Enqueue(i, "C", Payload(i, 1000));
        if (i % 50 == 0 && !w.Flush(5000)) return 11;
        if (w.stats().write_errors > 0) break;
    }
    w.Flush(5000);
    w.Stop();
    const LogWriterStats s = w.stats();
    if (s.write_errors < 1 || s.dropped_write_error < 1) return 12;
    const auto files = LogFiles(dir);
    if (files.size() != 1) return 13;
    const int n = CheckDeadLog(files[0], 1000);
    if (n <= 0 || n != s.events_written) return 14;
    // Cut back to the last complete event.
    if (static_cast<std::int64_t>(fs::file_size(files[0])) != s.bytes_written) return 15;
    if (static_cast<std::int64_t>(fs::file_size(files[0])) > expect_max_size) return 16;
    return 0;
}

TEST(LogWriterTest, FileSizeLimitIsAReportedErrorNotACrash) {
    const std::string dir = FreshDir("efbig");
    const pid_t child = ::fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
        ::signal(SIGXFSZ, SIG_IGN);
        rlimit lim{100'000, 100'000};
        if (::setrlimit(RLIMIT_FSIZE, &lim) != 0) ::_exit(20);
        ::_exit(WriteUntilErrorInChild(dir, 100'000));
    }
    int status = 0;
    ::waitpid(child, &status, 0);
    ASSERT_TRUE(WIFEXITED(status));
    EXPECT_EQ(WEXITSTATUS(status), 0);
}

TEST(LogWriterTest, FullTmpfsIsAReportedErrorNotACrash) {
    const std::string dir = FreshDir("tmpfs");
    const pid_t child = ::fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
        if (::unshare(CLONE_NEWNS) != 0) ::_exit(77);
        if (::mount(nullptr, "/", nullptr, MS_REC | MS_PRIVATE, nullptr) != 0) ::_exit(77);
        if (::mount("tmpfs", dir.c_str(), "tmpfs", 0, "size=256k") != 0) ::_exit(77);
        ::_exit(WriteUntilErrorInChild(dir, 256 * 1024));
    }
    int status = 0;
    ::waitpid(child, &status, 0);
    ASSERT_TRUE(WIFEXITED(status));
    if (WEXITSTATUS(status) == 77) GTEST_SKIP() << "no mount namespace here";
    EXPECT_EQ(WEXITSTATUS(status), 0);
}

// Issue 14 case 4: on a full disk every retry opens a new segment whose first event fails
// too. Such a segment holds no complete event and must not be left behind (shore tools choke
// on a 0-byte log): the directory keeps only the one file cut back to its last event.
int RetryOnFullDiskInChild(const std::string& dir) {
    LogWriterConfig c = BaseConfig(dir);
    c.error_retry_ms = 1;
    LogWriter w(c);
    if (!w.Start().ok()) return 10;
    int i = 0;
    for (; i < 2000 && w.stats().write_errors == 0; ++i) {
        w.Enqueue(i, "C", Payload(i, 1000));
        if (!w.Flush(5000)) return 11;
    }
    if (w.stats().write_errors == 0) return 12;
    // Retries: each one opens a new segment and fails on its first event.
    for (int k = 0; k < 200 && w.stats().write_errors < 4; ++k, ++i) {
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
        w.Enqueue(i, "C", Payload(i, 1000));
        if (!w.Flush(5000)) return 13;
    }
    w.Stop();
    const LogWriterStats s = w.stats();
    if (s.write_errors < 4) return 14;
    const auto files = LogFiles(dir);
    for (const auto& f : files) {
        if (fs::file_size(f) == 0) return 15;  // an empty segment left behind
    }
    if (files.size() != 1) return 16;
    if (CheckDeadLog(files[0], 1000) != s.events_written) return 17;
    return 0;
}

TEST(LogWriterTest, FullTmpfsRetriesLeaveNoEmptySegment) {
    const std::string dir = FreshDir("tmpfs_retry");
    const pid_t child = ::fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
        if (::unshare(CLONE_NEWNS) != 0) ::_exit(77);
        if (::mount(nullptr, "/", nullptr, MS_REC | MS_PRIVATE, nullptr) != 0) ::_exit(77);
        if (::mount("tmpfs", dir.c_str(), "tmpfs", 0, "size=256k") != 0) ::_exit(77);
        ::_exit(RetryOnFullDiskInChild(dir));
    }
    int status = 0;
    ::waitpid(child, &status, 0);
    ASSERT_TRUE(WIFEXITED(status));
    if (WEXITSTATUS(status) == 77) GTEST_SKIP() << "no mount namespace here";
    EXPECT_EQ(WEXITSTATUS(status), 0);
}

std::string ReadAll(std::FILE* f) {
    std::fflush(f);
    std::rewind(f);
    std::string out;
    char buf[4096];
    std::size_t n;
    while ((n = std::fread(buf, 1, sizeof(buf), f)) > 0) out.append(buf, n);
    return out;
}

// Events keep coming (one per pass) until a segment shows up in `dir` again (bounded; the
// writer notices at its next flush interval). Returns the next timestamp.
int FeedUntilSegmentIn(LogWriter& w, const std::string& dir, int next) {
    for (int k = 0; k < 2000; ++k) {
        std::error_code ec;
        if (fs::is_directory(dir, ec) && !LogFiles(dir).empty()) break;
        w.Enqueue(next, "C", Payload(next, 100));
        ++next;
        w.Flush(5000);
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    return next;
}

// Issue 14 case 6: the log directory is deleted under the running writer. It must notice
// (not write into the deleted file for ever), say so, count it, create the directory again
// and go on in a new segment there.
TEST(LogWriterTest, DeletedDirectoryIsReportedRecreatedAndLoggingGoesOn) {
    const std::string dir = FreshDir("deleted");
    LogWriterConfig c = BaseConfig(dir);
    c.flush_interval_ms = 20;
    std::FILE* said = std::tmpfile();
    ASSERT_NE(said, nullptr);
    RateLimitedLog human(said, 0);
    LogWriter w(c, {}, &human);
    ASSERT_TRUE(w.Start().ok());
    int next = 0;
    for (; next < 10; ++next) w.Enqueue(next, "C", Payload(next, 100));
    ASSERT_TRUE(w.Flush(5000));
    fs::remove_all(dir);
    next = FeedUntilSegmentIn(w, dir, next);
    ASSERT_TRUE(fs::is_directory(dir));
    for (int k = 0; k < 10; ++k, ++next) w.Enqueue(next, "C", Payload(next, 100));
    w.Stop();
    const auto files = LogFiles(dir);
    ASSERT_EQ(files.size(), 1u);
    const auto events = ReadLog(files[0]);
    ASSERT_GE(events.size(), 11u);  // at least what came after the new file opened
    for (std::size_t k = 0; k < events.size(); ++k) {
        EXPECT_EQ(events[k].timestamp, events.front().timestamp + static_cast<std::int64_t>(k));
        EXPECT_EQ(events[k].data, Payload(static_cast<int>(events[k].timestamp), 100));
    }
    EXPECT_EQ(events.back().timestamp, next - 1);
    const LogWriterStats s = w.stats();
    EXPECT_EQ(s.directory_lost, 1);
    // Everything before the new file went into the deleted one, and is counted as lost.
    EXPECT_EQ(s.events_lost, events.front().timestamp);
    EXPECT_EQ(s.events_written, next);
    EXPECT_EQ(s.directory, dir);
    const std::string text = ReadAll(said);
    std::fclose(said);
    EXPECT_NE(text.find("was deleted while open"), std::string::npos) << text;
    EXPECT_NE(text.find("created it again"), std::string::npos) << text;
}

// As above, but the directory cannot be made again (its parent became a file): the writer
// goes on in log.fallback_dir, and back in the primary once that works again.
TEST(LogWriterTest, UncreatableDirectorySwitchesToTheFallbackAndBack) {
    const std::string base = FreshDir("fallback");
    const std::string parent = base + "/mnt";
    const std::string dir = parent + "/logs";
    const std::string fallback = base + "/fallback";
    fs::create_directories(dir);
    LogWriterConfig c = BaseConfig(dir);
    c.fallback_directory = fallback;
    c.flush_interval_ms = 20;
    c.error_retry_ms = 1;
    std::FILE* said = std::tmpfile();
    ASSERT_NE(said, nullptr);
    RateLimitedLog human(said, 0);
    LogWriter w(c, {}, &human);
    ASSERT_TRUE(w.Start().ok());
    int next = 0;
    for (; next < 5; ++next) w.Enqueue(next, "C", Payload(next, 100));
    ASSERT_TRUE(w.Flush(5000));
    fs::remove_all(parent);
    {
        std::ofstream f(parent);  // mkdir -p of the primary now fails (ENOTDIR)
        f << "not a directory";
    }
    next = FeedUntilSegmentIn(w, fallback, next);
    ASSERT_EQ(LogFiles(fallback).size(), 1u);
    for (int k = 0; k < 5; ++k, ++next) w.Enqueue(next, "C", Payload(next, 100));
    ASSERT_TRUE(w.Flush(5000));
    EXPECT_EQ(w.stats().directory, fallback);
    EXPECT_EQ(w.stats().directory_lost, 1);
    // The primary can be made again: the next file (SIGHUP) goes there.
    fs::remove(parent);
    w.RequestRotate();
    for (int k = 0; k < 5; ++k, ++next) w.Enqueue(next, "C", Payload(next, 100));
    w.Stop();
    ASSERT_EQ(LogFiles(dir).size(), 1u);
    EXPECT_EQ(ReadLog(LogFiles(dir)[0]).size(), 5u);
    EXPECT_EQ(ReadLog(LogFiles(fallback)[0]).back().timestamp, next - 6);
    EXPECT_EQ(w.stats().directory, dir);
    const std::string text = ReadAll(said);
    std::fclose(said);
    EXPECT_NE(text.find("writing to fallback directory " + fallback), std::string::npos) << text;
    EXPECT_NE(text.find("writing to " + dir + " again"), std::string::npos) << text;
}

// The log directory's file system is unmounted (lazily, as `umount -l` does) under the writer:
// the path now leads to the directory underneath. The writer notices (the open segment is
// still linked, so nothing counts as lost), and goes on there. Exit code 0 = good.
int UnmountedInChild(const std::string& dir) {
    if (::mount("tmpfs", dir.c_str(), "tmpfs", 0, "size=1m") != 0) return 77;
    LogWriterConfig c = BaseConfig(dir);
    c.flush_interval_ms = 20;
    LogWriter w(c);
    if (!w.Start().ok()) return 10;
    int next = 0;
    for (; next < 10; ++next) w.Enqueue(next, "C", Payload(next, 100));
    if (!w.Flush(5000)) return 11;
    if (::umount2(dir.c_str(), MNT_DETACH) != 0) return 77;
    if (!LogFiles(dir).empty()) return 12;  // the directory underneath is empty
    next = FeedUntilSegmentIn(w, dir, next);
    for (int k = 0; k < 10; ++k, ++next) w.Enqueue(next, "C", Payload(next, 100));
    w.Stop();
    const LogWriterStats s = w.stats();
    if (s.directory_lost != 1 || s.events_lost != 0) return 13;
    const auto files = LogFiles(dir);
    if (files.size() != 1) return 14;
    const auto events = ReadLog(files[0]);
    if (events.size() < 11 || events.back().timestamp != next - 1) return 15;
    return 0;
}

TEST(LogWriterTest, UnmountedDirectoryIsNoticedAndLoggingGoesOnUnderneath) {
    const std::string dir = FreshDir("unmounted");
    const pid_t child = ::fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
        if (::unshare(CLONE_NEWNS) != 0) ::_exit(77);
        if (::mount(nullptr, "/", nullptr, MS_REC | MS_PRIVATE, nullptr) != 0) ::_exit(77);
        ::_exit(UnmountedInChild(dir));
    }
    int status = 0;
    ::waitpid(child, &status, 0);
    ASSERT_TRUE(WIFEXITED(status));
    if (WEXITSTATUS(status) == 77) GTEST_SKIP() << "no mount namespace here";
    EXPECT_EQ(WEXITSTATUS(status), 0);
}

TEST(LogWriterTest, FilesAreCreated0640) {
    const std::string dir = FreshDir("mode");
    const mode_t old = ::umask(0);
    LogWriter w(BaseConfig(dir));
    ASSERT_TRUE(w.Start().ok());
    w.Enqueue(0, "C", Payload(0, 10));
    w.Stop();
    ::umask(old);
    const auto files = LogFiles(dir);
    ASSERT_EQ(files.size(), 1u);
    struct stat st {};
    ASSERT_EQ(::stat(files[0].c_str(), &st), 0);
    EXPECT_EQ(st.st_mode & 0777, 0640u);
}

TEST(LogWriterTest, ConfigValidationAndMissingDirectory) {
    LogWriterConfig bad;
    bad.prefix = "a/b";
    bad.flush_interval_ms = 0;
    EXPECT_EQ(bad.Validate().size(), 3u);  // directory, prefix, flush interval
    LogWriterConfig c = BaseConfig(::testing::TempDir() + "does/not/exist");
    LogWriter w(c);
    EXPECT_FALSE(w.Start().ok());
    EXPECT_FALSE(w.Enqueue(0, "C", {}) && w.Flush(10));
}

}  // namespace
}  // namespace pitmap::acq
