// SPDX-License-Identifier: MIT
// Raw head session tests (spec imagenex_deltat.md §3.1): switch data command field by field,
// return packet encode/decode, and the HeadReplyFramer matrix with byte accounting.
#include "common/protocol/deltat/head.hpp"

#include <gtest/gtest.h>

#include <random>

#include "tests/protocol/deltat/deltat_test_util.hpp"
#include "tests/support/stream_cuts.hpp"

namespace pitmap::protocol::deltat {
namespace {

using test_util::Drain;
using test_util::Event;
using Bytes = std::vector<std::uint8_t>;

SwitchCommand SampleCommand() {
    SwitchCommand c;
    c.head_id = 0x10;
    c.range_m = 30;
    c.range_offset = 0;
    c.nadir_offset_raw = 0xC000;  // 270 deg
    c.start_gain_db = 6;
    c.logf = 1;
    c.absorption_centi_db_per_m = 10;
    c.agc_threshold = 120;
    c.packet_number = 13;
    c.pulse_length_us = 180;
    c.data_points = 16000;
    c.data_bits = 8;
    c.orientation_request = 0x80;
    c.run_mode = 0x10;
    c.switch_delay_ms = 20;
    c.frequency_code = 86;
    return c;
}

TEST(SwitchCommand, EncodesEveryByteOfTheTable) {
    const Bytes b = EncodeSwitchCommand(SampleCommand());
    ASSERT_EQ(b.size(), 27u);
    const Bytes expected = {0xFE, 0x44, 0x10, 30, 0, 0xC0, 0x00, 0,    6,    1, 10, 120, 0,   13,
                            18,   0,    0,    0,  0, 16,   8,    0x80, 0x10, 0, 10, 86,  0xFD};
    EXPECT_EQ(b, expected);
}

TEST(SwitchCommand, DecodeRoundTripAndHelpers) {
    const auto d = DecodeSwitchCommand(EncodeSwitchCommand(SampleCommand()));
    ASSERT_TRUE(std::holds_alternative<SwitchCommand>(d));
    const SwitchCommand& c = std::get<SwitchCommand>(d);
    EXPECT_EQ(c.head_id, 0x10);
    EXPECT_EQ(c.range_m, 30);
    EXPECT_EQ(c.nadir_offset_raw, 0xC000);
    EXPECT_DOUBLE_EQ(c.nadir_offset_deg(), 270.0);
    EXPECT_EQ(c.start_gain_db, 6);
    EXPECT_EQ(c.logf, 1);
    EXPECT_EQ(c.absorption_centi_db_per_m, 10);
    EXPECT_EQ(c.agc_threshold, 120);
    EXPECT_EQ(c.packet_number, 13);
    EXPECT_EQ(c.pulse_length_us, 180);
    EXPECT_EQ(c.data_points, 16000);
    EXPECT_EQ(c.packets(), 16);
    EXPECT_EQ(c.data_bits, 8);
    EXPECT_EQ(c.orientation_request, 0x80);
    EXPECT_TRUE(c.agc());
    EXPECT_EQ(c.switch_delay_ms, 20);
    EXPECT_EQ(c.frequency_code, 86);
    EXPECT_EQ(c.frequency_khz(), 260);
    SwitchCommand f;
    f.frequency_code = 83;
    EXPECT_EQ(f.frequency_khz(), 245);
    f.frequency_code = 169;
    EXPECT_EQ(f.frequency_khz(), 675);
    EXPECT_EQ(EncodeSwitchCommand(c), EncodeSwitchCommand(SampleCommand()));
}

TEST(SwitchCommand, DecoderRejectsBadCommands) {
    const Bytes good = EncodeSwitchCommand(SampleCommand());
    const auto kind_of = [](const Bytes& b) {
        const auto d = DecodeSwitchCommand(b);
        EXPECT_TRUE(std::holds_alternative<DecodeError>(d));
        return std::holds_alternative<DecodeError>(d) ? std::get<DecodeError>(d) : DecodeError{};
    };
    Bytes b = good;
    b[0] = 0xFF;
    EXPECT_EQ(kind_of(b).kind, DecodeErrorKind::kBadMarker);
    b = good;
    b[26] = 0xFC;
    EXPECT_EQ(kind_of(b).kind, DecodeErrorKind::kBadTerminator);
    EXPECT_EQ(kind_of(b).offset, 26u);
    b = good;
    b[19] = 12;
    EXPECT_EQ(kind_of(b).kind, DecodeErrorKind::kBadValue);
    EXPECT_EQ(kind_of(b).offset, 19u);
    b = good;
    b[19] = 8;  // 8 packets, packet number 13
    EXPECT_EQ(kind_of(b).kind, DecodeErrorKind::kBadValue);
    EXPECT_EQ(kind_of(b).offset, 13u);
    b = good;
    b.pop_back();
    EXPECT_EQ(kind_of(b).kind, DecodeErrorKind::kTruncated);
    b = good;
    b.push_back(0);
    EXPECT_EQ(kind_of(b).kind, DecodeErrorKind::kTrailingBytes);
}

TEST(SwitchCommand, EncoderRejectsUnencodableValues) {
    SwitchCommand c = SampleCommand();
    c.pulse_length_us = 185;
    EXPECT_TRUE(EncodeSwitchCommand(c).empty());
    c = SampleCommand();
    c.switch_delay_ms = 3;
    EXPECT_TRUE(EncodeSwitchCommand(c).empty());
    c = SampleCommand();
    c.data_points = 12000;
    EXPECT_TRUE(EncodeSwitchCommand(c).empty());
    c = SampleCommand();
    c.data_points = 8000;  // packet 13 >= 8
    EXPECT_TRUE(EncodeSwitchCommand(c).empty());
}

HeadReply SampleReply(std::uint8_t packet, char mode = 'U') {
    HeadReply h;
    h.mode = static_cast<std::uint8_t>(mode);
    h.head_id = 0x10;
    h.serial_status = 0x41;
    h.packet_number = packet;
    h.firmware_version = 7;
    h.range_m = 50;
    h.bytes_8_9 = {0x11, 0x22};
    h.data_bytes_be = 1000;
    h.byte_12 = 0x33;
    h.orientation_type = packet == 0 ? 1 : 0;
    h.pitch_raw = 16384;  // 90 deg
    h.roll_raw = -8192;   // -45 deg
    h.heading_raw = 0x7FFF;
    for (std::size_t i = 0; i < h.bytes_20_31.size(); ++i) {
        h.bytes_20_31[i] = static_cast<std::uint8_t>(0xA0 + i);
    }
    for (std::size_t i = 0; i < h.data.size(); ++i) {
        h.data[i] = static_cast<std::uint8_t>((i * 7 + packet) & 0x3F);  // never 'I' (0x49)
    }
    return h;
}

TEST(HeadReply, EncodesTheTable) {
    const Bytes b = EncodeHeadReply(SampleReply(3));
    ASSERT_EQ(b.size(), 1033u);
    EXPECT_EQ(b[0], 'I');
    EXPECT_EQ(b[1], 'U');
    EXPECT_EQ(b[2], 'X');
    EXPECT_EQ(b[3], 0x10);
    EXPECT_EQ(b[4], 0x41);
    EXPECT_EQ(b[5], 3);
    EXPECT_EQ(b[6], 7);
    EXPECT_EQ(b[7], 50);
    EXPECT_EQ(b[10], 0x03);
    EXPECT_EQ(b[11], 0xE8);
    EXPECT_EQ(b[13], 0);
    EXPECT_EQ(b[14], 0x00);  // pitch 16384 little-endian
    EXPECT_EQ(b[15], 0x40);
    EXPECT_EQ(b[16], 0x00);  // roll -8192 = 0xE000
    EXPECT_EQ(b[17], 0xE0);
    EXPECT_EQ(b[20], 0xA0);
    EXPECT_EQ(b[31], 0xAB);
    EXPECT_EQ(b[32], 3);  // data[0]
    EXPECT_EQ(b[1032], 0xFC);
}

TEST(HeadReply, DecodeRoundTripAndAngles) {
    const Bytes b = EncodeHeadReply(SampleReply(0, 'V'));
    const auto d = DecodeHeadReply(b);
    ASSERT_TRUE(std::holds_alternative<HeadReply>(d));
    const HeadReply& h = std::get<HeadReply>(d);
    EXPECT_EQ(h.mode, 'V');
    EXPECT_EQ(h.packet_number, 0);
    EXPECT_TRUE(h.orientation_valid());
    EXPECT_DOUBLE_EQ(h.pitch_deg(), 90.0);
    EXPECT_DOUBLE_EQ(h.roll_deg(), -45.0);
    EXPECT_EQ(h.data_bytes(), 1000);
    EXPECT_EQ(h.data[999], (999 * 7) & 0x3F);
    EXPECT_EQ(EncodeHeadReply(h), b);
    HeadReply swapped = h;
    swapped.data_bytes_be = 0xE803;  // 1000 little-endian: byte order [U]
    EXPECT_EQ(swapped.data_bytes(), 1000);
    swapped.data_bytes_be = 0x0101;
    EXPECT_EQ(swapped.data_bytes(), 0x0101);
    HeadReply bad_mode = h;
    bad_mode.mode = 'W';
    EXPECT_TRUE(EncodeHeadReply(bad_mode).empty());
}

TEST(HeadReply, DecoderRejectsBadPackets) {
    const Bytes good = EncodeHeadReply(SampleReply(1));
    Bytes b = good;
    b[1032] = 0xFD;
    auto d = DecodeHeadReply(b);
    ASSERT_TRUE(std::holds_alternative<DecodeError>(d));
    EXPECT_EQ(std::get<DecodeError>(d).kind, DecodeErrorKind::kBadTerminator);
    EXPECT_EQ(std::get<DecodeError>(d).offset, 1032u);
    b = good;
    b[1] = 'W';
    d = DecodeHeadReply(b);
    EXPECT_EQ(std::get<DecodeError>(d).kind, DecodeErrorKind::kBadMarker);
    d = DecodeHeadReply(ByteSpan(good.data(), 1032));
    EXPECT_EQ(std::get<DecodeError>(d).kind, DecodeErrorKind::kTruncated);
    b = good;
    b.push_back(0);
    d = DecodeHeadReply(b);
    EXPECT_EQ(std::get<DecodeError>(d).kind, DecodeErrorKind::kTrailingBytes);
}

struct Outcome {
    std::vector<Bytes> frames;
    std::vector<Skipped> skipped;
};

Outcome FeedHead(const Bytes& stream,
                 const std::vector<std::size_t>& cuts,
                 std::uint8_t head_id = kDefaultHeadId) {
    HeadReplyFramer framer(head_id);
    std::vector<Event> events;
    std::uint64_t next = 0;
    std::size_t start = 0;
    auto push_until = [&](std::size_t end) {
        framer.Push(ByteSpan(stream.data() + start, end - start));
        start = end;
        Drain<HeadReplyFramer, HeadFrame>(framer, events, &next);
        EXPECT_LT(framer.buffered(), kHeadReplyBytes);
    };
    for (std::size_t cut : cuts) push_until(cut);
    push_until(stream.size());
    Outcome o;
    // End: the waiting packet gives up its sync; what it held is framed again.
    while (auto tail = framer.Flush()) {
        EXPECT_EQ(tail->offset, next);
        next += tail->bytes;
        o.skipped.push_back(*tail);
        Drain<HeadReplyFramer, HeadFrame>(framer, events, &next);
    }
    EXPECT_EQ(framer.buffered(), 0u);
    EXPECT_EQ(next, stream.size());  // every byte exactly once
    for (auto& e : events) {
        if (e.kind == Event::Kind::kFrame) {
            o.frames.push_back(e.bytes);
        } else {
            o.skipped.push_back(e.skipped);
        }
    }
    return o;
}

std::uint64_t SkippedBytes(const Outcome& o, SkipReason reason) {
    std::uint64_t n = 0;
    for (const auto& s : o.skipped) n += s.reason == reason ? s.bytes : 0;
    return n;
}

Bytes PingPackets(std::size_t n) {
    Bytes out;
    for (std::size_t k = 0; k < n; ++k) {
        const Bytes p = EncodeHeadReply(SampleReply(static_cast<std::uint8_t>(k)));
        out.insert(out.end(), p.begin(), p.end());
    }
    return out;
}

TEST(HeadReplyFramer, CompletePing) {
    const Bytes stream = PingPackets(8);
    const Outcome o = FeedHead(stream, {});
    ASSERT_EQ(o.frames.size(), 8u);
    EXPECT_TRUE(o.skipped.empty());
    for (std::size_t k = 0; k < 8; ++k) {
        const auto d = DecodeHeadReply(o.frames[k]);
        ASSERT_TRUE(std::holds_alternative<HeadReply>(d));
        EXPECT_EQ(std::get<HeadReply>(d).packet_number, k);
    }
}

TEST(HeadReplyFramer, IncompleteAndTruncated) {
    const Bytes stream = PingPackets(1);
    HeadReplyFramer framer;
    framer.Push(ByteSpan(stream.data(), 1032));
    EXPECT_TRUE(std::holds_alternative<NeedMore>(framer.Next()));
    framer.Push(ByteSpan(stream.data() + 1032, 1));
    EXPECT_TRUE(std::holds_alternative<HeadFrame>(framer.Next()));
    EXPECT_FALSE(framer.Flush().has_value());
    Bytes cut = PingPackets(2);
    cut.resize(1033 + 500);
    const Outcome o = FeedHead(cut, {});
    ASSERT_EQ(o.frames.size(), 1u);
    ASSERT_EQ(o.skipped.size(), 1u);
    EXPECT_EQ(o.skipped[0].reason, SkipReason::kTruncated);
    EXPECT_EQ(o.skipped[0].bytes, 500u);
    EXPECT_EQ(o.skipped[0].offset, 1033u);
}

TEST(HeadReplyFramer, SplitAtEveryOffset) {
    const Bytes stream = PingPackets(2);
    pitmap::test::ForEverySingleCut(stream.size(), [&](const auto& cuts, std::size_t cut) {
        const Outcome o = FeedHead(stream, cuts);
        ASSERT_EQ(o.frames.size(), 2u) << cut;
        EXPECT_TRUE(o.skipped.empty()) << cut;
    });
}

TEST(HeadReplyFramer, ByteByByteAndRandomChunks) {
    const Bytes stream = PingPackets(4);
    EXPECT_EQ(FeedHead(stream, pitmap::test::EveryByteCuts(stream.size())).frames.size(), 4u);
    std::mt19937 rng(7);
    for (int trial = 0; trial < 50; ++trial) {
        const Outcome o = FeedHead(stream, pitmap::test::RandomCuts(stream.size(), 1500, rng));
        ASSERT_EQ(o.frames.size(), 4u);
        EXPECT_TRUE(o.skipped.empty());
    }
}

TEST(HeadReplyFramer, GarbageBeforeAndBetween) {
    const Bytes p0 = EncodeHeadReply(SampleReply(0));
    const Bytes p1 = EncodeHeadReply(SampleReply(1));
    Bytes stream = {'I', 'U', 'Y', 'I', 'X', 0x10, 'I', 'V', 'X', 0x11, 0xFC};  // 11 bytes
    stream.insert(stream.end(), p0.begin(), p0.end());
    stream.insert(stream.end(), {'I', 'I', 'U'});
    stream.insert(stream.end(), p1.begin(), p1.end());
    const Outcome o = FeedHead(stream, {});
    ASSERT_EQ(o.frames.size(), 2u);
    EXPECT_EQ(o.frames[0], p0);
    EXPECT_EQ(o.frames[1], p1);
    EXPECT_EQ(SkippedBytes(o, SkipReason::kGarbage), 14u);
}

TEST(HeadReplyFramer, FakeSyncInsideData) {
    HeadReply h = SampleReply(2);
    const std::uint8_t fake[4] = {'I', 'U', 'X', 0x10};
    for (int i = 0; i < 4; ++i) h.data[100 + i] = fake[i];
    const Bytes p = EncodeHeadReply(h);
    Bytes stream = p;
    stream.insert(stream.end(), p.begin(), p.end());
    const Outcome o = FeedHead(stream, {});
    ASSERT_EQ(o.frames.size(), 2u);
    EXPECT_TRUE(o.skipped.empty());
}

TEST(HeadReplyFramer, BadTerminatorResyncs) {
    Bytes bad = EncodeHeadReply(SampleReply(0));
    bad[1032] = 0x00;
    const Bytes good = EncodeHeadReply(SampleReply(1));
    Bytes stream = bad;
    stream.insert(stream.end(), good.begin(), good.end());
    const Outcome o = FeedHead(stream, {});
    ASSERT_EQ(o.frames.size(), 1u);
    EXPECT_EQ(o.frames[0], good);
    EXPECT_EQ(SkippedBytes(o, SkipReason::kBadTerminator), 3u);
    EXPECT_EQ(SkippedBytes(o, SkipReason::kGarbage), 1030u);
    EXPECT_EQ(o.skipped.front().reason, SkipReason::kBadTerminator);
    EXPECT_EQ(o.skipped.front().offset, 0u);
}

TEST(HeadReplyFramer, OverLongPacketLeavesGarbage) {
    // A packet with 5 extra bytes before its terminator: the terminator check fails at 1032.
    Bytes longer = EncodeHeadReply(SampleReply(0));
    longer.insert(longer.end() - 1, 5, std::uint8_t{0x20});
    const Bytes good = EncodeHeadReply(SampleReply(1));
    Bytes stream = longer;
    stream.insert(stream.end(), good.begin(), good.end());
    const Outcome o = FeedHead(stream, {});
    ASSERT_EQ(o.frames.size(), 1u);
    EXPECT_EQ(o.frames[0], good);
    EXPECT_EQ(SkippedBytes(o, SkipReason::kBadTerminator), 3u);
    EXPECT_EQ(SkippedBytes(o, SkipReason::kGarbage), longer.size() - 3);
}

TEST(HeadReplyFramer, OtherHeadIdIsGarbage) {
    const Bytes stream = PingPackets(2);
    const Outcome o = FeedHead(stream, {}, 0x11);
    EXPECT_TRUE(o.frames.empty());
    EXPECT_EQ(SkippedBytes(o, SkipReason::kGarbage), stream.size());
}

}  // namespace
}  // namespace pitmap::protocol::deltat
