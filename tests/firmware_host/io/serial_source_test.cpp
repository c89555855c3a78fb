// SPDX-License-Identifier: MIT
// SerialSource through a pseudo-terminal pair: raw bytes both ways, unplug and replug.
#include "firmware_host/io/serial_source.hpp"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <pty.h>
#include <termios.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

namespace pitmap::acq {
namespace {

namespace fs = std::filesystem;

// A pty pair whose slave the source opens through a symlink (like /dev/serial/by-id/...).
struct Pty {
    int master = -1;
    std::string slave_path;
    bool Open() {
        int slave = -1;
        char name[128] = {};
        if (::openpty(&master, &slave, name, nullptr, nullptr) != 0) return false;
        // The master side raw too, so the test's own writes are not processed.
        termios t{};
        ::tcgetattr(slave, &t);
        ::cfmakeraw(&t);
        ::tcsetattr(slave, TCSANOW, &t);
        ::close(slave);  // the source opens it by path
        slave_path = name;
        return true;
    }
    void Close() {
        if (master >= 0) ::close(master);
        master = -1;
    }
    ~Pty() { Close(); }
};

std::string Link(const std::string& name) {
    return ::testing::TempDir() + name + "_" + std::to_string(::getpid());
}

void PointLink(const std::string& link, const std::string& target) {
    const std::string tmp = link + ".tmp";
    fs::remove(tmp);
    fs::create_symlink(target, tmp);
    fs::rename(tmp, link);  // atomic replace, as udev does
}

std::vector<std::byte> ReadAtLeast(ByteSource& src, std::size_t n) {
    std::vector<std::byte> got;
    Chunk chunk;
    for (int i = 0; i < 200 && got.size() < n; ++i) {
        auto r = src.Read(chunk, 50);
        if (r.ok() && *r == ReadOutcome::kData) {
            EXPECT_GT(chunk.utime_host, 0);
            got.insert(got.end(), chunk.data.begin(), chunk.data.end());
        }
    }
    return got;
}

std::vector<std::byte> AwkwardBytes() {
    // \r \n ^C ^D NUL 0xFF XON XOFF, DEL, ESC, then all 256 values.
    std::vector<std::byte> v;
    for (int b : {0x0D, 0x0A, 0x03, 0x04, 0x00, 0xFF, 0x11, 0x13, 0x7F, 0x1B, 0x0D, 0x0D, 0x0A}) {
        v.push_back(static_cast<std::byte>(b));
    }
    for (int b = 0; b < 256; ++b) v.push_back(static_cast<std::byte>(b));
    return v;
}

std::vector<std::byte> ReadMaster(int fd, std::size_t n) {
    std::vector<std::byte> got;
    for (int i = 0; i < 100 && got.size() < n; ++i) {
        pollfd p{fd, POLLIN, 0};
        if (::poll(&p, 1, 50) <= 0) continue;
        std::byte buf[1024];
        const long k = ::read(fd, buf, sizeof(buf));
        if (k > 0) got.insert(got.end(), buf, buf + k);
    }
    return got;
}

SerialConfig Config(const std::string& path) {
    SerialConfig c;
    c.path = path;
    c.baud = 460800;
    c.reopen_backoff = {.initial_ms = 10, .max_ms = 40, .factor = 2.0};
    return c;
}

TEST(SerialSourceTest, RawBytesPassUnchangedBothWays) {
    Pty pty;
    ASSERT_TRUE(pty.Open());
    SerialSource src(Config(pty.slave_path));
    ASSERT_TRUE(src.Open().ok()) << src.last_error();
    EXPECT_EQ(src.state(), SourceState::kOpen);
    EXPECT_EQ(src.transport(), Transport::kSerial);

    const std::vector<std::byte> bytes = AwkwardBytes();
    ASSERT_EQ(::write(pty.master, bytes.data(), bytes.size()), static_cast<long>(bytes.size()));
    EXPECT_EQ(ReadAtLeast(src, bytes.size()), bytes);  // no echo, no CR/NL mapping, no ISIG

    ASSERT_TRUE(src.Write(bytes, 1000).ok());
    EXPECT_EQ(ReadMaster(pty.master, bytes.size()), bytes);  // no OPOST, no ONLCR
    // Nothing echoed back into the stream.
    Chunk chunk;
    auto r = src.Read(chunk, 20);
    ASSERT_TRUE(r.ok());
    EXPECT_EQ(*r, ReadOutcome::kTimeout);
}

TEST(SerialSourceTest, UnsupportedBaudIsAConfigProblem) {
    SerialConfig c = Config("/dev/null");
    c.baud = 123456;
    const auto problems = c.Validate();
    ASSERT_EQ(problems.size(), 1u);
    EXPECT_NE(problems[0].find("921600"), std::string::npos);
    EXPECT_EQ(SupportedBaudRates().back(), 921600);
}

TEST(SerialSourceTest, NotATerminalIsAnError) {
    const std::string path = Link("notatty");
    {
        std::FILE* f = std::fopen(path.c_str(), "w");
        std::fclose(f);
    }
    SerialSource src(Config(path));
    auto s = src.Open();
    fs::remove(path);
    ASSERT_FALSE(s.ok());
    EXPECT_NE(s.error().message.find("not a terminal"), std::string::npos);
    EXPECT_EQ(src.state(), SourceState::kDisconnected);
}

TEST(SerialSourceTest, ExclusiveOpen) {
    Pty pty;
    ASSERT_TRUE(pty.Open());
    SerialSource a(Config(pty.slave_path));
    SerialSource b(Config(pty.slave_path));
    ASSERT_TRUE(a.Open().ok());
    auto s = b.Open();
    ASSERT_FALSE(s.ok());
    EXPECT_NE(s.error().message.find("in use"), std::string::npos) << s.error().message;
}

TEST(SerialSourceTest, UnplugAndReplugThroughAStablePath) {
    const std::string link = Link("by-id");
    Pty first;
    ASSERT_TRUE(first.Open());
    PointLink(link, first.slave_path);
    SerialSource src(Config(link));
    ASSERT_TRUE(src.Open().ok());
    EXPECT_EQ(src.generation(), 1);
    const std::vector<std::byte> hello{std::byte{'A'}, std::byte{'\r'}, std::byte{'\n'}};
    ASSERT_EQ(::write(first.master, hello.data(), hello.size()), 3);
    EXPECT_EQ(ReadAtLeast(src, 3), hello);

    // Unplug: the device disappears.
    first.Close();
    fs::remove(link);
    bool lost = false;
    Chunk chunk;
    for (int i = 0; i < 50 && !lost; ++i) {
        auto r = src.Read(chunk, 20);
        lost = !r.ok();
    }
    ASSERT_TRUE(lost);
    EXPECT_EQ(src.state(), SourceState::kDisconnected);
    EXPECT_FALSE(src.last_error().empty());
    // Still gone: reads time out or report the failed reopen, never crash.
    for (int i = 0; i < 5; ++i) (void)src.Read(chunk, 20);
    EXPECT_EQ(src.state(), SourceState::kDisconnected);

    // Replug: a new pty behind the same stable path.
    Pty second;
    ASSERT_TRUE(second.Open());
    PointLink(link, second.slave_path);
    const std::vector<std::byte> again{
        std::byte{0x00}, std::byte{0xAA}, std::byte{0x44}, std::byte{0x12}};
    std::vector<std::byte> got;
    for (int i = 0; i < 100 && got.size() < again.size(); ++i) {
        auto r = src.Read(chunk, 20);
        if (src.state() == SourceState::kOpen && src.generation() == 2 && got.empty() && i >= 0) {
            static bool written = false;
            if (!written) {
                ASSERT_EQ(::write(second.master, again.data(), again.size()), 4);
                written = true;
            }
        }
        if (r.ok() && *r == ReadOutcome::kData)
            got.insert(got.end(), chunk.data.begin(), chunk.data.end());
    }
    EXPECT_EQ(got, again);
    EXPECT_EQ(src.reconnects(), 1);
    EXPECT_EQ(src.generation(), 2);
    fs::remove(link);
}

}  // namespace
}  // namespace pitmap::acq
