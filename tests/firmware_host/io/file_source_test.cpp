// SPDX-License-Identifier: MIT
// FileSource: replays a file in chunks, byte for byte, optionally paced; Backoff bounds.
#include "firmware_host/io/file_source.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "firmware_host/io/backoff.hpp"

namespace pitmap::acq {
namespace {

std::string WriteFile(const std::string& name, const std::vector<char>& bytes) {
    const std::string path = ::testing::TempDir() + name;
    std::ofstream f(path, std::ios::binary);
    f.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    return path;
}

TEST(FileSourceTest, ReplaysEveryByteInOddChunks) {
    std::vector<char> bytes(10'000);
    for (std::size_t i = 0; i < bytes.size(); ++i) bytes[i] = static_cast<char>(i * 13);
    const std::string path = WriteFile("file_source_replay.bin", bytes);
    FileSource src({.path = path, .chunk_bytes = 777});
    ASSERT_TRUE(src.Open().ok());
    std::vector<char> got;
    Chunk chunk;
    int chunks = 0;
    for (int i = 0; i < 100; ++i) {
        auto r = src.Read(chunk, 100);
        ASSERT_TRUE(r.ok());
        if (*r == ReadOutcome::kEndOfStream) break;
        ASSERT_EQ(*r, ReadOutcome::kData);
        EXPECT_LE(chunk.data.size(), 777u);
        for (std::byte b : chunk.data) got.push_back(static_cast<char>(b));
        ++chunks;
    }
    EXPECT_EQ(got, bytes);
    EXPECT_EQ(chunks, 13);  // ceil(10000 / 777)
    EXPECT_EQ(src.state(), SourceState::kFinished);
    auto again = src.Read(chunk, 10);
    ASSERT_TRUE(again.ok());
    EXPECT_EQ(*again, ReadOutcome::kEndOfStream);
    EXPECT_FALSE(src.Write(chunk.data, 10).ok());
}

TEST(FileSourceTest, PacingHoldsChunksBack) {
    const std::string path = WriteFile("file_source_paced.bin", std::vector<char>(1000, 'x'));
    // 100 kB/s: the second 500-byte chunk is due 5 ms after the first.
    FileSource src({.path = path, .chunk_bytes = 500, .bytes_per_second = 100'000});
    Chunk chunk;
    auto r = src.Read(chunk, 0);
    ASSERT_TRUE(r.ok());
    EXPECT_EQ(*r, ReadOutcome::kData);
    r = src.Read(chunk, 0);  // not due yet, and no time to wait
    ASSERT_TRUE(r.ok());
    EXPECT_EQ(*r, ReadOutcome::kTimeout);
    r = src.Read(chunk, 1000);
    ASSERT_TRUE(r.ok());
    EXPECT_EQ(*r, ReadOutcome::kData);
}

TEST(FileSourceTest, MissingFileIsAnError) {
    FileSource src({.path = ::testing::TempDir() + "no_such_file.bin"});
    Chunk chunk;
    EXPECT_FALSE(src.Open().ok());
    EXPECT_FALSE(src.Read(chunk, 10).ok());
    EXPECT_FALSE(src.last_error().empty());
}

TEST(BackoffTest, GrowsToTheBoundAndResets) {
    Backoff b({.initial_ms = 100, .max_ms = 1000, .factor = 2.0});
    EXPECT_TRUE(b.Ready(0));
    std::vector<std::int64_t> delays;
    for (int i = 0; i < 6; ++i) {
        b.Failed(0);
        delays.push_back(b.current_delay_ms());
    }
    EXPECT_EQ(delays, (std::vector<std::int64_t>{100, 200, 400, 800, 1000, 1000}));
    EXPECT_FALSE(b.Ready(999'999));
    EXPECT_TRUE(b.Ready(1'000'000));
    b.Succeeded();
    EXPECT_TRUE(b.Ready(0));
    b.Failed(0);
    EXPECT_EQ(b.current_delay_ms(), 100);
}

}  // namespace
}  // namespace pitmap::acq
