// SPDX-License-Identifier: MIT
// Framer matrix after NovAtel EDIE's framer tests (shared/specs/novatel_oem.md §1-§5, §9).
#include "common/protocol/novatel/framer.hpp"

#include <gtest/gtest.h>

#include <random>

#include "common/protocol/novatel/crc32.hpp"
#include "tests/protocol/novatel/test_util.hpp"
#include "tests/support/stream_cuts.hpp"

namespace pitmap::protocol::novatel {
namespace {

using testing::AsciiLine;
using testing::Bytes;
using testing::FrameAll;
using testing::FromHex;
using testing::FromText;
using testing::LongFrame;
using testing::ShortFrame;

// §4: real TIMEB frame from the oem7 driver's time.gps.
const Bytes kTimeB = FromHex(
    "aa44121c 65000040 2c000000 a2b41608 60a65e0e 20400002 24990080"
    "00000000 3fdc41c9af91123e 52580931837b133e ce550a00000032c0"
    "e3070000 09 0a 12 39 b0b30000 01000000 46ed42b9");

// §5: binary response to LOG (GAVLab ParsingData.GPS).
const Bytes kLogResponse = FromHex(
    "aa44121c 0100 80 20 0600 0000 ff b4 9706 1d3dfd18 00000000 ffff 0000 01000000 4f4b ea247892");

constexpr std::string_view kBestPosA =
    "#BESTPOSA,COM1,0,83.5,FINESTEERING,1419,336148.000,02000040,6145,2724;SOL_COMPUTED,SINGLE,"
    "51.11636418888,-114.03832502118,1064.9520,-16.2712,WGS84,1.6961,1.3636,3.6449,\"\",0.000,"
    "0.000,8,8,8,8,0,0,0,06,0,03*f181ad10\r\n";

Bytes Concat(std::initializer_list<Bytes> parts) {
    Bytes out;
    for (const auto& p : parts) out.insert(out.end(), p.begin(), p.end());
    return out;
}

// One of every frame kind, in a stream.
Bytes MixedStream() {
    Bytes body(40);
    for (std::size_t i = 0; i < body.size(); ++i) body[i] = static_cast<std::uint8_t>(i * 7);
    return Concat({kTimeB,
                   FromText("\r\n<OK\r\n[COM1]"),
                   ShortFrame(508, body),
                   FromText(kBestPosA),
                   AsciiLine('%', "INSPVASA,2209,490712.000;1,2,3"),
                   FromText("$GPGGA,1*4B\r\n"),
                   LongFrame(0x1234, body, 0, 0x45),
                   FromText("<ERROR:Invalid Message\r\n"),
                   kLogResponse,
                   FromText("[ICOM1]"),
                   kTimeB});
}

TEST(NovatelCrc, CheckValue) {
    EXPECT_EQ(Crc32(FromText("123456789")), 0x2DFD2D88u);
}

TEST(NovatelCrc, SpecVectors) {
    ASSERT_EQ(kTimeB.size(), 76u);
    EXPECT_EQ(Crc32(ByteSpan(kTimeB.data(), 72)), 0xB942ED46u);
    EXPECT_EQ(Crc32(kTimeB), 0u);  // residue property
    ASSERT_EQ(kLogResponse.size(), 38u);
    EXPECT_EQ(Crc32(ByteSpan(kLogResponse.data(), 34)), 0x927824EAu);
    const std::string_view inner = kBestPosA.substr(1, kBestPosA.find('*') - 1);
    EXPECT_EQ(Crc32(FromText(inner)), 0xF181AD10u);
}

TEST(NovatelCrc, ShortHeaderVectorFromIns2) {
    const Bytes file = testing::ReadFile("oem7drv_ins2.gps");
    ASSERT_GE(file.size(), 212u);
    const Bytes frame(file.begin() + 136, file.begin() + 212);
    EXPECT_EQ(frame[3], 0x3C);
    EXPECT_EQ(Crc32(ByteSpan(frame.data(), 72)), 0xA9F3879Fu);
    const auto ev = FrameAll(frame);
    ASSERT_EQ(ev.frames.size(), 1u);
    EXPECT_EQ(ev.frames[0].kind, FrameKind::kShortBinary);
    EXPECT_EQ(ev.frames[0].message_id, 1362);
}

TEST(NovatelFramer, CompleteFrame) {
    const auto ev = FrameAll(kTimeB);
    ASSERT_EQ(ev.frames.size(), 1u);
    EXPECT_TRUE(ev.skips.empty());
    EXPECT_EQ(ev.frames[0].kind, FrameKind::kLongBinary);
    EXPECT_EQ(ev.frames[0].message_id, 101);
    EXPECT_EQ(ev.frames[0].offset, 0u);
    EXPECT_EQ(ev.frames[0].bytes, kTimeB);
}

TEST(NovatelFramer, IncompleteFrameWaitsThenFlushReportsTruncated) {
    Framer framer;
    framer.Push(ByteSpan(kTimeB.data(), kTimeB.size() - 1));
    EXPECT_TRUE(std::holds_alternative<NeedMore>(framer.Next()));
    EXPECT_EQ(framer.buffered(), 75u);
    const auto tail = framer.Flush();
    ASSERT_TRUE(tail.has_value());
    EXPECT_EQ(tail->reason, SkipReason::kTruncated);
    EXPECT_EQ(tail->offset, 0u);
    // Only the sync and the bytes after it that start no frame are given up; the rest is
    // framed again and holds no frame.
    std::size_t skipped = tail->bytes;
    for (;;) {
        auto ev = framer.Next();
        if (std::holds_alternative<NeedMore>(ev)) {
            auto more = framer.Flush();
            if (!more) break;
            skipped += more->bytes;
            continue;
        }
        ASSERT_TRUE(std::holds_alternative<Skipped>(ev));
        skipped += std::get<Skipped>(ev).bytes;
    }
    EXPECT_EQ(skipped, 75u);
    EXPECT_EQ(framer.buffered(), 0u);
    EXPECT_FALSE(framer.Flush().has_value());
    // The framer continues after a flush, offsets counting on.
    framer.Push(kTimeB);
    auto r = framer.Next();
    ASSERT_TRUE(std::holds_alternative<Frame>(r));
    EXPECT_EQ(std::get<Frame>(r).offset, 75u);
}

TEST(NovatelFramer, ExpireKeepsARealFrameCutByAPause) {
    Framer framer;
    framer.Push(ByteSpan(kTimeB.data(), 30));
    EXPECT_TRUE(std::holds_alternative<NeedMore>(framer.Next()));
    EXPECT_FALSE(framer.Expire().has_value());
    framer.Push(ByteSpan(kTimeB.data() + 30, kTimeB.size() - 30));
    auto r = framer.Next();
    ASSERT_TRUE(std::holds_alternative<Frame>(r));
    EXPECT_EQ(std::get<Frame>(r).bytes.size(), kTimeB.size());
}

TEST(NovatelFramer, ExpireGivesUpAFalseSyncWithAFrameBehind) {
    Bytes fake = {0xAA, 0x44, 0x12, 0x1C, 0, 0, 0, 0, 0x10, 0x75};
    fake.resize(28, 0x11);
    const Bytes stream = Concat({fake, kTimeB});
    Framer framer;
    framer.Push(stream);
    EXPECT_TRUE(std::holds_alternative<NeedMore>(framer.Next()));
    const auto tail = framer.Expire();
    ASSERT_TRUE(tail.has_value());
    EXPECT_EQ(tail->reason, SkipReason::kStale);
    EXPECT_EQ(tail->offset, 0u);
    EXPECT_EQ(tail->bytes, 28u);
    auto r = framer.Next();
    ASSERT_TRUE(std::holds_alternative<Frame>(r));
    EXPECT_EQ(std::get<Frame>(r).offset, 28u);
}

TEST(NovatelFramer, EveryFrameKind) {
    const Bytes stream = MixedStream();
    const auto ev = FrameAll(stream);
    const std::vector<FrameKind> kinds = {FrameKind::kLongBinary,
                                          FrameKind::kAbbreviated,
                                          FrameKind::kPrompt,
                                          FrameKind::kShortBinary,
                                          FrameKind::kAscii,
                                          FrameKind::kShortAscii,
                                          FrameKind::kNmea,
                                          FrameKind::kProprietary,
                                          FrameKind::kAbbreviated,
                                          FrameKind::kLongBinary,
                                          FrameKind::kPrompt,
                                          FrameKind::kLongBinary};
    ASSERT_EQ(ev.frames.size(), kinds.size());
    for (std::size_t i = 0; i < kinds.size(); ++i) EXPECT_EQ(ev.frames[i].kind, kinds[i]) << i;
    EXPECT_EQ(ev.frames[3].message_id, 508);
    EXPECT_EQ(ev.frames[4].message_id, 42);
    EXPECT_EQ(ev.frames[5].message_id, 508);
    EXPECT_EQ(ev.frames[9].message_id, 1);
    // Only the CR LF before "<OK" is not part of a frame.
    ASSERT_EQ(ev.skips.size(), 1u);
    EXPECT_EQ(ev.skips[0].reason, SkipReason::kGarbage);
    EXPECT_EQ(ev.skips[0].bytes, 2u);
    EXPECT_EQ(ev.skips[0].offset, 76u);
}

TEST(NovatelFramer, SplitAtEveryOffset) {
    const Bytes stream = MixedStream();
    const auto whole = FrameAll(stream);
    pitmap::test::ForEverySingleCut(stream.size(), [&](const auto& cuts, std::size_t cut) {
        const auto split = FrameAll(stream, pitmap::test::PieceSizes(cuts, stream.size()));
        ASSERT_EQ(split.frames, whole.frames) << "split at " << cut;
        ASSERT_EQ(split.counters.TotalBytes(), whole.counters.TotalBytes()) << cut;
    });
}

TEST(NovatelFramer, ByteByByteAndRandomChunks) {
    const Bytes stream = MixedStream();
    const auto whole = FrameAll(stream);
    EXPECT_EQ(FrameAll(stream, {1}).frames, whole.frames);
    std::mt19937 rng(42);
    for (int trial = 0; trial < 50; ++trial) {
        const auto ev =
            FrameAll(stream,
                     pitmap::test::PieceSizes(pitmap::test::RandomCuts(stream.size(), 97, rng),
                                              stream.size()));
        ASSERT_EQ(ev.frames, whole.frames) << trial;
        ASSERT_EQ(ev.skips.size(), whole.skips.size()) << trial;
    }
}

TEST(NovatelFramer, GarbageBeforeAndBetweenFrames) {
    const Bytes stream = Concat({FromText("xyz\x01"), kTimeB, FromHex("00 ff aa 44 aa"), kTimeB});
    const auto ev = FrameAll(stream);
    ASSERT_EQ(ev.frames.size(), 2u);
    EXPECT_EQ(ev.frames[0].offset, 4u);
    EXPECT_EQ(ev.frames[1].offset, 4u + 76u + 5u);
    ASSERT_EQ(ev.skips.size(), 2u);
    EXPECT_EQ(ev.skips[0].reason, SkipReason::kGarbage);
    EXPECT_EQ(ev.skips[0].bytes, 4u);
    EXPECT_EQ(ev.skips[1].reason, SkipReason::kGarbage);
    EXPECT_EQ(ev.skips[1].bytes, 5u);
    EXPECT_EQ(ev.skips[1].offset, 80u);
}

TEST(NovatelFramer, SyncBytesInsidePayload) {
    // The payload holds a complete long sync + header, '#', '<', '[' and '$'.
    Bytes body = FromHex("aa44121c 65000040 2c00 aa4413 23 3c 5b 24 aa4512");
    body.resize(60, 0xAA);
    const Bytes frame = LongFrame(42, body);
    const auto ev = FrameAll(Concat({frame, frame}));
    ASSERT_EQ(ev.frames.size(), 2u);
    EXPECT_TRUE(ev.skips.empty());
    EXPECT_EQ(ev.frames[1].offset, frame.size());
}

TEST(NovatelFramer, BadCrcSkipsOneByteAndRecovers) {
    Bytes bad = kTimeB;
    bad[40] ^= 0x01;
    const auto ev = FrameAll(Concat({bad, kTimeB}));
    ASSERT_EQ(ev.frames.size(), 1u);
    EXPECT_EQ(ev.frames[0].offset, 76u);
    ASSERT_EQ(ev.skips.size(), 2u);
    EXPECT_EQ(ev.skips[0].reason, SkipReason::kBadCrc);
    EXPECT_EQ(ev.skips[0].bytes, 1u);
    EXPECT_EQ(ev.skips[0].offset, 0u);
    EXPECT_EQ(ev.skips[1].reason, SkipReason::kGarbage);
    EXPECT_EQ(ev.skips[1].bytes, 75u);
    EXPECT_EQ(ev.counters.Events(SkipReason::kBadCrc), 1u);
}

TEST(NovatelFramer, BadAsciiCrcAndNmeaChecksum) {
    Bytes line = FromText(kBestPosA);
    line[20] = 'X';
    const Bytes nmea = FromText("$GPGGA,1*35\r\n");
    const auto ev = FrameAll(Concat({line, nmea, FromText(kBestPosA)}));
    ASSERT_EQ(ev.frames.size(), 1u);
    EXPECT_EQ(ev.frames[0].kind, FrameKind::kAscii);
    EXPECT_EQ(ev.counters.Events(SkipReason::kBadCrc), 2u);
}

TEST(NovatelFramer, TerminalEscapeInjectedIntoFrame) {
    // §9 item 2: a VT220 reply inside a binary frame; the next frame must be recovered.
    const Bytes esc = FromText("\x1b[?62;9;c");
    Bytes broken = kTimeB;
    broken.insert(broken.begin() + 50, esc.begin(), esc.end());
    const auto ev = FrameAll(Concat({kTimeB, broken, kTimeB, FromText(kBestPosA)}));
    ASSERT_EQ(ev.frames.size(), 3u);
    EXPECT_EQ(ev.frames[0].offset, 0u);
    EXPECT_EQ(ev.frames[1].offset, 76u + 85u);
    EXPECT_EQ(ev.frames[2].kind, FrameKind::kAscii);
    EXPECT_EQ(ev.counters.Events(SkipReason::kBadCrc), 1u);
    EXPECT_EQ(ev.counters.Bytes(SkipReason::kBadCrc) + ev.counters.Bytes(SkipReason::kGarbage),
              85u);
}

TEST(NovatelFramer, RuntAndOverLongLengths) {
    Bytes runt = kTimeB;
    runt[3] = 20;  // header length < 28
    Bytes too_long = kTimeB;
    too_long[8] = 0xE1;  // message length 0x7FE1 + 28 + 4 > 32768
    too_long[9] = 0x7F;
    const auto ev = FrameAll(Concat({runt, too_long, kTimeB}));
    ASSERT_EQ(ev.frames.size(), 1u);
    EXPECT_EQ(ev.frames[0].offset, 152u);
    EXPECT_EQ(ev.counters.Events(SkipReason::kBadLength), 2u);
    EXPECT_EQ(ev.counters.Bytes(SkipReason::kBadLength), 2u);
    EXPECT_EQ(ev.skips[0].reason, SkipReason::kBadLength);
    EXPECT_EQ(ev.skips[0].offset, 0u);
}

TEST(NovatelFramer, LongestLegalFrameAccepted) {
    const Bytes body(kMaxLongFrameLength - 32, 0x5A);
    const Bytes frame = LongFrame(140, body);
    ASSERT_EQ(frame.size(), kMaxLongFrameLength);
    const auto ev = FrameAll(frame, {1000});
    ASSERT_EQ(ev.frames.size(), 1u);
    EXPECT_EQ(ev.frames[0].bytes.size(), kMaxLongFrameLength);
}

TEST(NovatelFramer, TruncatedEndOfStream) {
    const auto ev = FrameAll(Concat({kTimeB, Bytes(kTimeB.begin(), kTimeB.begin() + 20)}));
    ASSERT_EQ(ev.frames.size(), 1u);
    ASSERT_EQ(ev.skips.size(), 1u);
    EXPECT_EQ(ev.skips[0].reason, SkipReason::kTruncated);
    EXPECT_EQ(ev.skips[0].bytes, 20u);
    EXPECT_EQ(ev.skips[0].offset, 76u);
}

TEST(NovatelFramer, TextNeverSwallowsBinarySync) {
    // A '#' "line" that runs into a binary frame (§9 item 1).
    const auto ev = FrameAll(Concat(
        {FromText("#BESTPOSA,COM1,0"), kTimeB, FromText("<OK"), kTimeB, FromText("[COM"), kTimeB}));
    ASSERT_EQ(ev.frames.size(), 3u);
    for (const auto& f : ev.frames) EXPECT_EQ(f.kind, FrameKind::kLongBinary);
    EXPECT_EQ(ev.counters.Bytes(SkipReason::kGarbage), 16u + 3u + 4u);
}

TEST(NovatelFramer, PromptSyntax) {
    const auto good = FrameAll(FromText("[COM1][ICOM1][USB1][COM1_30][COM]"));
    ASSERT_EQ(good.frames.size(), 5u);
    EXPECT_EQ(good.frames[3].bytes, FromText("[COM1_30]"));
    EXPECT_TRUE(good.skips.empty());
    const auto bad = FrameAll(FromText("[com1][COM1_][1COM][COM1 ]"));
    EXPECT_TRUE(bad.frames.empty());
    EXPECT_EQ(bad.counters.Bytes(SkipReason::kGarbage), 26u);
}

TEST(NovatelFramer, ShortHeaderLengthUsesBodyByte) {
    const Bytes frame = ShortFrame(325, Bytes(255, 0x11));
    ASSERT_EQ(frame.size(), kMaxShortFrameLength);
    const auto ev = FrameAll(Concat({frame, ShortFrame(325, {})}));
    ASSERT_EQ(ev.frames.size(), 2u);
    EXPECT_EQ(ev.frames[1].bytes.size(), 16u);
}

TEST(NovatelFramer, BufferStaysBounded) {
    Framer framer;
    const Bytes garbage(100000, 0x00);
    framer.Push(garbage);
    auto r = framer.Next();
    ASSERT_TRUE(std::holds_alternative<Skipped>(r));
    EXPECT_EQ(std::get<Skipped>(r).bytes, 100000u);
    EXPECT_TRUE(std::holds_alternative<NeedMore>(framer.Next()));
    EXPECT_EQ(framer.buffered(), 0u);
    // A header promising 32000 bytes holds at most that much back.
    Bytes head = LongFrame(140, Bytes(32000 - 32, 0));
    head.resize(5000);
    framer.Push(head);
    EXPECT_TRUE(std::holds_alternative<NeedMore>(framer.Next()));
    EXPECT_EQ(framer.buffered(), 5000u);
    EXPECT_EQ(framer.bytes_pushed(), 105000u);
}

TEST(NovatelFramer, AsciiIdsFromNames) {
    EXPECT_EQ(MessageIdFromName("INSPVAX"), 1465);
    EXPECT_EQ(MessageIdFromName("BESTPOS"), 42);
    EXPECT_FALSE(MessageIdFromName("NOSUCHLOG").has_value());
    EXPECT_EQ(MessageNameFromId(2264), "CORRIMUS");
    const auto ev = FrameAll(AsciiLine('#', "NOSUCHLOGA,COM1;1"));
    ASSERT_EQ(ev.frames.size(), 1u);
    EXPECT_EQ(ev.frames[0].message_id, -1);
}

}  // namespace
}  // namespace pitmap::protocol::novatel
