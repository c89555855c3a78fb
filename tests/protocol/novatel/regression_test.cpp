// SPDX-License-Identifier: MIT
// Real captures (tests/data/novatel/PROVENANCE.md): exact per-id frame counts, zero CRC
// failures except the one documented terminal-reply injection, truncated tail reported.
// The pcap captures are covered by the capture library's tests.
#include <gtest/gtest.h>

#include <map>
#include <utility>

#include "common/protocol/novatel/decoder.hpp"
#include "tests/protocol/novatel/test_util.hpp"

namespace pitmap::protocol::novatel {
namespace {

using Counts = std::map<std::pair<FrameKind, std::int32_t>, int>;

struct FileResult {
    Counts counts;
    testing::Events events;
    int decode_errors = 0;
};

FileResult FrameFile(const std::string& name, const std::vector<std::size_t>& chunks = {}) {
    FileResult r;
    const auto data = testing::ReadFile(name);
    r.events = testing::FrameAll(data, chunks);
    for (const auto& f : r.events.frames) {
        r.counts[{f.kind, f.message_id}]++;
        const auto d = Decode(Frame{f.kind, f.message_id, ByteSpan(f.bytes), f.offset});
        if (std::holds_alternative<DecodeError>(d)) ++r.decode_errors;
    }
    return r;
}

constexpr auto kL = FrameKind::kLongBinary;
constexpr auto kS = FrameKind::kShortBinary;
constexpr auto kA = FrameKind::kAscii;
constexpr auto kAbbrev = FrameKind::kAbbreviated;
constexpr auto kPrompt = FrameKind::kPrompt;

void ExpectClean(const FileResult& r) {
    EXPECT_EQ(r.events.counters.Events(SkipReason::kBadCrc), 0u);
    EXPECT_EQ(r.events.counters.Events(SkipReason::kBadLength), 0u);
    EXPECT_EQ(r.events.counters.Events(SkipReason::kTruncated), 0u);
    EXPECT_EQ(r.decode_errors, 0);
}

TEST(NovatelCaptures, Oem7Driver) {
    auto r = FrameFile("oem7drv_align.gps");
    ExpectClean(r);
    EXPECT_EQ(r.counts, (Counts{{{kL, 1335}, 12}}));

    r = FrameFile("oem7drv_bestpos.gps");
    ExpectClean(r);
    EXPECT_EQ(r.counts,
              (Counts{{{kL, 42}, 5},
                      {{kL, 99}, 5},
                      {{kL, 726}, 2},
                      {{kL, 1163}, 2},
                      {{kL, 1465}, 2},
                      {{kS, 508}, 10},
                      {{kAbbrev, -1}, 8},
                      {{kPrompt, -1}, 8}}));
    // Only the CR LF before each "<OK" is outside a frame.
    EXPECT_EQ(r.events.counters.Bytes(SkipReason::kGarbage), 16u);

    r = FrameFile("oem7drv_ins1.gps");
    ExpectClean(r);
    EXPECT_EQ(r.counts,
              (Counts{{{kS, 508}, 243}, {{kS, 2264}, 10}, {{kL, 2051}, 29}, {{kL, 1945}, 2}}));
    EXPECT_EQ(r.events.counters.TotalBytes(), 0u);

    r = FrameFile("oem7drv_ins2.gps");
    ExpectClean(r);
    EXPECT_EQ(r.counts,
              (Counts{{{kS, 1362}, 766}, {{kS, 508}, 62}, {{kL, 1465}, 6}, {{kL, 1945}, 1}}));

    r = FrameFile("oem7drv_ins2_humble.gps");
    ExpectClean(r);
    EXPECT_EQ(r.counts,
              (Counts{{{kS, 1362}, 7},
                      {{kS, 508}, 4},
                      {{kL, 1465}, 4},
                      {{kL, 1945}, 3},
                      {{kA, 94}, 3},
                      {{kPrompt, -1}, 1}}));

    r = FrameFile("oem7drv_rxstatus.gps");
    ExpectClean(r);
    EXPECT_EQ(r.counts, (Counts{{{kL, 93}, 3}}));

    r = FrameFile("oem7drv_time.gps");
    ExpectClean(r);
    EXPECT_EQ(r.counts, (Counts{{{kL, 101}, 6}}));
}

TEST(NovatelCaptures, GavlabOneEachAndParsingData) {
    auto r = FrameFile("gavlab_OneEach.GPS");
    ExpectClean(r);
    int binary = 0;
    for (const auto& [key, n] : r.counts) {
        if (key.first == kL) {
            EXPECT_EQ(n, 1) << key.second;
            ++binary;
        }
    }
    EXPECT_EQ(binary, 8);
    EXPECT_EQ((r.counts[{kA, 177}]), 7);  // #SENDR

    r = FrameFile("gavlab_OneEach.ASC");
    ExpectClean(r);
    EXPECT_EQ(r.events.frames.size(), 15u);
    EXPECT_EQ(r.events.counters.TotalBytes(), 0u);

    r = FrameFile("gavlab_ParsingData.GPS");
    ExpectClean(r);
    int total_binary = 0;
    for (const auto& [key, n] : r.counts) total_binary += key.first == kL ? n : 0;
    EXPECT_EQ(total_binary, 288);
    EXPECT_EQ((r.counts[{kL, 42}]), 84);
    EXPECT_EQ((r.counts[{kL, 48}]), 83);
    EXPECT_EQ((r.counts[{kL, 83}]), 83);
}

TEST(NovatelCaptures, GavlabTest2OneInjectedCrcFailure) {
    for (const auto& chunks :
         {std::vector<std::size_t>{}, std::vector<std::size_t>{1448, 7, 513}}) {
        auto r = FrameFile("gavlab_test2_rcvr1.dat", chunks);
        EXPECT_EQ(r.events.counters.Events(SkipReason::kBadCrc), 1u);
        EXPECT_EQ(r.events.counters.Bytes(SkipReason::kBadCrc), 1u);
        EXPECT_EQ(r.events.counters.Events(SkipReason::kTruncated), 0u);
        EXPECT_EQ(r.decode_errors, 0);
        EXPECT_EQ((r.counts[{kL, 140}]), 436);
        EXPECT_EQ((r.counts[{kL, 241}]), 448);
        EXPECT_EQ((r.counts[{kL, 7}]), 13);
        int binary = 0;
        for (const auto& [key, n] : r.counts) binary += key.first == kL ? n : 0;
        EXPECT_EQ(binary, 897);
        // Frames after the failure are recovered: the last frame ends at the end of the file.
        ASSERT_FALSE(r.events.frames.empty());
        std::uint64_t crc_offset = 0;
        for (const auto& s : r.events.skips) {
            if (s.reason == SkipReason::kBadCrc) crc_offset = s.offset;
        }
        int after = 0;
        for (const auto& f : r.events.frames) after += f.offset > crc_offset ? 1 : 0;
        EXPECT_GT(after, 0);
    }
}

TEST(NovatelCaptures, RtklibTruncatedTail) {
    const auto r = FrameFile("rtklib_oemv_200911218.gps", {4096});
    EXPECT_EQ(r.events.counters.Events(SkipReason::kBadCrc), 0u);
    EXPECT_EQ(r.decode_errors, 0);
    EXPECT_EQ(r.counts,
              (Counts{{{kL, 41}, 25},
                      {{kL, 42}, 49},
                      {{kL, 48}, 49},
                      {{kL, 83}, 50},
                      {{kL, 140}, 46},
                      {{kL, 287}, 90},
                      {{kL, 723}, 8},
                      {{kAbbrev, -1}, 5},
                      {{kPrompt, -1}, 5}}));
    ASSERT_FALSE(r.events.skips.empty());
    const Skipped& tail = r.events.skips.back();
    EXPECT_EQ(tail.reason, SkipReason::kTruncated);
    EXPECT_EQ(tail.offset + tail.bytes, 262144u);
    EXPECT_LT(tail.bytes, 28u);  // cut inside a header
    EXPECT_EQ(r.events.counters.Events(SkipReason::kTruncated), 1u);
}

}  // namespace
}  // namespace pitmap::protocol::novatel
