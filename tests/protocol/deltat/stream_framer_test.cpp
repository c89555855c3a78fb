// SPDX-License-Identifier: MIT
// 83P StreamFramer and DecodeDatagram tests (spec imagenex_deltat.md §1.1, §3.2, §4.1-4.2):
// the parser matrix of the style guide — complete, incomplete, split at every offset, byte by
// byte, random chunks, garbage before/between, a fake `83P` marker inside beam data, bad N,
// truncated end, over-long — with the byte-accounting invariant checked on every event.
// Streams are synthesised with the encoder (no real Delta T capture exists, spec §5).
#include "common/protocol/deltat/stream_framer.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <string_view>

#include "tests/protocol/deltat/deltat_test_util.hpp"
#include "tests/support/stream_cuts.hpp"

namespace pitmap::protocol::deltat {
namespace {

using test_util::Drain;
using test_util::Event;
using test_util::MakePing;
using test_util::PutU16Be;

using Bytes = std::vector<std::uint8_t>;

void Append(Bytes& out, const Bytes& more) {
    out.insert(out.end(), more.begin(), more.end());
}
void Append(Bytes& out, std::string_view text) {
    out.insert(out.end(), text.begin(), text.end());
}

// Four records of every size class: 2176 (480 + intensity), 496 (120), 256 (comment),
// 736 (240, v1.00).
std::vector<Bytes> SampleRecords() {
    return {EncodeRecord83P(MakePing(480, true, 10, 1)),
            EncodeRecord83P(MakePing(120, false, 10, 2)),
            EncodeComment83P("mbcopy comment"),
            EncodeRecord83P(MakePing(240, false, 0, 3))};
}

Bytes Concat(const std::vector<Bytes>& records) {
    Bytes out;
    for (const auto& r : records) Append(out, r);
    return out;
}

struct Outcome {
    std::vector<Bytes> frames;
    std::vector<std::uint64_t> frame_offsets;
    std::vector<Skipped> skipped;
    std::uint64_t accounted = 0;
};

// Feeds `stream` in chunks cut at `cuts` (sorted offsets), drains after each push; at the cuts
// listed in `pauses` the input stops long enough for Expire(); flushes at the end.
Outcome FeedStream(const Bytes& stream,
                   const std::vector<std::size_t>& cuts,
                   const std::vector<std::size_t>& pauses = {}) {
    StreamFramer framer;
    std::vector<Event> events;
    std::uint64_t next = 0;
    std::size_t start = 0;
    auto push_until = [&](std::size_t end) {
        framer.Push(ByteSpan(stream.data() + start, end - start));
        start = end;
        Drain<StreamFramer, Record>(framer, events, &next);
        EXPECT_LE(framer.buffered(), kMaxRecordBytes + 2);
    };
    const auto give_up = [&](bool end) {
        // The waiting candidate gives up its marker; what it held is framed again.
        while (auto tail = end ? framer.Flush() : framer.Expire()) {
            EXPECT_EQ(tail->offset, next);
            EXPECT_EQ(tail->reason, end ? SkipReason::kTruncated : SkipReason::kStale);
            Event e;
            e.kind = Event::Kind::kSkipped;
            e.skipped = *tail;
            events.push_back(e);
            next += tail->bytes;
            Drain<StreamFramer, Record>(framer, events, &next);
        }
    };
    for (std::size_t cut : cuts) {
        push_until(cut);
        if (std::find(pauses.begin(), pauses.end(), cut) != pauses.end()) give_up(false);
    }
    push_until(stream.size());
    give_up(true);
    EXPECT_EQ(framer.Flush(), std::nullopt);
    EXPECT_EQ(framer.buffered(), 0u);
    EXPECT_EQ(framer.bytes_pushed(), stream.size());
    Outcome o;
    o.accounted = next;
    for (auto& e : events) {
        if (e.kind == Event::Kind::kFrame) {
            o.frames.push_back(e.bytes);
            o.frame_offsets.push_back(e.offset);
        } else {
            o.skipped.push_back(e.skipped);
        }
    }
    EXPECT_EQ(o.accounted, stream.size());  // every byte exactly once
    return o;
}

std::uint64_t SkippedBytes(const Outcome& o, SkipReason reason) {
    std::uint64_t n = 0;
    for (const auto& s : o.skipped) n += s.reason == reason ? s.bytes : 0;
    return n;
}

TEST(StreamFramer, CompleteRecords) {
    const auto records = SampleRecords();
    const Bytes stream = Concat(records);
    const Outcome o = FeedStream(stream, {});
    ASSERT_EQ(o.frames.size(), 4u);
    EXPECT_TRUE(o.skipped.empty());
    std::uint64_t offset = 0;
    for (std::size_t i = 0; i < 4; ++i) {
        EXPECT_EQ(o.frames[i], records[i]);
        EXPECT_EQ(o.frame_offsets[i], offset);
        offset += records[i].size();
    }
    // The framed records decode: ping numbers 1, 2, a comment, 3.
    FloatOrderMemory memory;
    EXPECT_EQ(std::get<Ping83P>(DecodeRecord83P(o.frames[0], memory)).ping_number, 1u);
    EXPECT_EQ(std::get<Ping83P>(DecodeRecord83P(o.frames[1], memory)).ping_number, 2u);
    EXPECT_EQ(std::get<Comment83P>(DecodeRecord83P(o.frames[2], memory)).text_view(),
              "mbcopy comment");
    EXPECT_EQ(std::get<Ping83P>(DecodeRecord83P(o.frames[3], memory)).ping_number, 3u);
}

TEST(StreamFramer, RecordLayoutReported) {
    StreamFramer framer;
    const Bytes r = EncodeRecord83P(MakePing(240, true, 10));
    framer.Push(r);
    auto ev = framer.Next();
    ASSERT_TRUE(std::holds_alternative<Record>(ev));
    const Record& rec = std::get<Record>(ev);
    EXPECT_EQ(rec.layout.num_beams, 240);
    EXPECT_TRUE(rec.layout.intensity);
    EXPECT_EQ(rec.layout.total_bytes, 1216);
    EXPECT_EQ(rec.bytes.size(), 1216u);
    EXPECT_TRUE(std::holds_alternative<NeedMore>(framer.Next()));
}

TEST(StreamFramer, IncompleteRecordNeedsMoreThenTruncated) {
    const Bytes r = EncodeRecord83P(MakePing(480, false, 10));
    StreamFramer framer;
    framer.Push(ByteSpan(r.data(), 700));
    EXPECT_TRUE(std::holds_alternative<NeedMore>(framer.Next()));
    EXPECT_EQ(framer.buffered(), 700u);
    const auto tail = framer.Flush();
    ASSERT_TRUE(tail.has_value());
    EXPECT_EQ(tail->reason, SkipReason::kTruncated);
    EXPECT_EQ(tail->offset, 0u);
    // The marker and the garbage after it; the rest is framed again and holds no record.
    std::uint64_t skipped = tail->bytes;
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
    EXPECT_EQ(skipped, 700u);
}

// A valid-looking header claiming 2176 bytes, then real records, then the end of the stream
// or a pause: the old Flush() dropped the real records with it. Now only the false marker is
// given up and the records behind it are framed.
TEST(StreamFramer, FalseHeaderBeforeTheEndOrAPauseKeepsTheRecordsBehind) {
    const Bytes big = EncodeRecord83P(MakePing(480, true, 10, 9));
    const Bytes false_header(big.begin(), big.begin() + 256);
    const Bytes a = EncodeRecord83P(MakePing(120, false, 10, 1));
    const Bytes b = EncodeRecord83P(MakePing(240, false, 0, 2));
    Bytes stream = a;
    Append(stream, false_header);
    Append(stream, b);
    Append(stream, a);
    ASSERT_LT(stream.size() - a.size(), big.size());  // the false record never completes
    for (const bool pause : {false, true}) {
        const std::size_t cut = stream.size() - a.size();
        const Outcome o = pause ? FeedStream(stream, {cut}, {cut}) : FeedStream(stream, {});
        ASSERT_EQ(o.frames.size(), 3u) << "pause " << pause;
        EXPECT_EQ(o.frames[0], a);
        EXPECT_EQ(o.frames[1], b);
        EXPECT_EQ(o.frames[2], a);
        EXPECT_EQ(SkippedBytes(o, pause ? SkipReason::kStale : SkipReason::kTruncated) +
                      SkippedBytes(o, SkipReason::kGarbage),
                  256u);
    }
    // Enough real records behind it for the false record to "complete": it holds their
    // headers and is not followed by a marker, so it is not trusted; nothing is swallowed.
    Bytes longer = a;
    Append(longer, false_header);
    for (const Bytes* r : {&b, &a, &b, &a}) Append(longer, *r);
    ASSERT_GT(longer.size() - a.size(), big.size());
    for (const std::vector<std::size_t>& cuts :
         {std::vector<std::size_t>{}, std::vector<std::size_t>{600, 1300, 2900}}) {
        const Outcome o = FeedStream(longer, cuts);
        ASSERT_EQ(o.frames.size(), 5u);
        EXPECT_EQ(o.frames[1], b);
        EXPECT_EQ(o.frames[4], a);
        EXPECT_EQ(SkippedBytes(o, SkipReason::kBadLength) + SkippedBytes(o, SkipReason::kGarbage),
                  256u);
    }
    // Back to back, before the end.
    Bytes two = a;
    Append(two, false_header);
    Append(two, false_header);
    Append(two, b);
    const Outcome o = FeedStream(two, {});
    ASSERT_EQ(o.frames.size(), 2u);
    EXPECT_EQ(o.frames[1], b);
}

TEST(StreamFramer, SplitAtEveryOffset) {
    const auto records = SampleRecords();
    const Bytes stream = Concat({records[1], records[2], records[3]});
    pitmap::test::ForEverySingleCut(stream.size(), [&](const auto& cuts, std::size_t cut) {
        const Outcome o = FeedStream(stream, cuts);
        ASSERT_EQ(o.frames.size(), 3u) << "cut " << cut;
        EXPECT_TRUE(o.skipped.empty()) << "cut " << cut;
        EXPECT_EQ(o.frames[0], records[1]);
        EXPECT_EQ(o.frames[2], records[3]);
    });
}

TEST(StreamFramer, ByteByByte) {
    const auto records = SampleRecords();
    const Bytes stream = Concat(records);
    const Outcome o = FeedStream(stream, pitmap::test::EveryByteCuts(stream.size()));
    ASSERT_EQ(o.frames.size(), 4u);
    EXPECT_TRUE(o.skipped.empty());
    EXPECT_EQ(o.frames[0], records[0]);
}

TEST(StreamFramer, RandomChunks) {
    const auto records = SampleRecords();
    Bytes stream;
    for (int rep = 0; rep < 5; ++rep) Append(stream, Concat(records));
    std::mt19937 rng(42);
    for (int trial = 0; trial < 50; ++trial) {
        const Outcome o = FeedStream(stream, pitmap::test::RandomCuts(stream.size(), 3000, rng));
        ASSERT_EQ(o.frames.size(), 20u);
        EXPECT_TRUE(o.skipped.empty());
        EXPECT_EQ(o.frames[19], records[3]);
    }
}

TEST(StreamFramer, GarbageBeforeAndBetween) {
    const auto records = SampleRecords();
    Bytes stream;
    const std::string_view before = "junk 8 83 83Q 3P P8 \x00\xff 88";  // no complete marker
    const std::string_view between = "8x83";
    Append(stream, before);
    Append(stream, records[0]);
    Append(stream, between);
    Append(stream, records[1]);
    Append(stream, "\r\n");
    Append(stream, records[2]);
    const Outcome o = FeedStream(stream, {});
    ASSERT_EQ(o.frames.size(), 3u);
    EXPECT_EQ(o.frames[0], records[0]);
    EXPECT_EQ(o.frames[1], records[1]);
    EXPECT_EQ(o.frames[2], records[2]);
    EXPECT_EQ(o.frame_offsets[0], before.size());
    EXPECT_EQ(SkippedBytes(o, SkipReason::kGarbage), before.size() + between.size() + 2);
    EXPECT_EQ(SkippedBytes(o, SkipReason::kBadLength), 0u);
    // Same stream byte by byte gives the same frames and the same skipped total.
    const Outcome b = FeedStream(stream, pitmap::test::EveryByteCuts(stream.size()));
    EXPECT_EQ(b.frames, o.frames);
    EXPECT_EQ(SkippedBytes(b, SkipReason::kGarbage), before.size() + between.size() + 2);
}

TEST(StreamFramer, FakeMarkerInsideBeamData) {
    Ping83P ping = MakePing(120, false, 10);
    // Beams 10-12 spell "83P" + a plausible-looking header start.
    ping.range_counts[10] = 0x3833;  // '8' '3'
    ping.range_counts[11] = 0x5000;  // 'P', version 0
    ping.range_counts[12] = 0x01F0;  // N = 496
    const Bytes r = EncodeRecord83P(ping);
    const Bytes stream = Concat({r, r, r});
    const Outcome o = FeedStream(stream, {});
    ASSERT_EQ(o.frames.size(), 3u);
    EXPECT_TRUE(o.skipped.empty());
    // After losing sync (first record's marker corrupted) the fake marker is rejected by
    // validation and the next real record is found.
    Bytes broken = stream;
    broken[0] = 'X';
    const Outcome b = FeedStream(broken, {});
    ASSERT_EQ(b.frames.size(), 2u);
    EXPECT_EQ(b.frame_offsets[0], r.size());
    EXPECT_EQ(SkippedBytes(b, SkipReason::kBadLength), 3u);  // the fake marker
    EXPECT_EQ(SkippedBytes(b, SkipReason::kGarbage), r.size() - 3);
}

TEST(StreamFramer, FakeMarkerInGarbageBeforeRecord) {
    const Bytes r = EncodeRecord83P(MakePing(480, false, 10));
    Bytes stream;
    Append(stream, std::string_view("83P\x0a\x04\xc0", 6));  // says N = 1216, then a record
    Append(stream, r);
    const Outcome o = FeedStream(stream, {});
    ASSERT_EQ(o.frames.size(), 1u);
    EXPECT_EQ(o.frames[0], r);
    EXPECT_EQ(o.frame_offsets[0], 6u);
    EXPECT_EQ(SkippedBytes(o, SkipReason::kBadLength), 3u);
    EXPECT_EQ(SkippedBytes(o, SkipReason::kGarbage), 3u);
}

TEST(StreamFramer, BadLengthIsSkippedAndResynced) {
    const auto records = SampleRecords();
    Bytes bad = records[1];  // 120 beams, N = 496
    PutU16Be(bad, 4, 498);   // N inconsistent with B
    const Bytes stream = Concat({records[0], bad, records[3]});
    const Outcome o = FeedStream(stream, {});
    ASSERT_EQ(o.frames.size(), 2u);
    EXPECT_EQ(o.frames[0], records[0]);
    EXPECT_EQ(o.frames[1], records[3]);
    EXPECT_EQ(SkippedBytes(o, SkipReason::kBadLength), 3u);
    EXPECT_EQ(SkippedBytes(o, SkipReason::kGarbage), bad.size() - 3);
    // B = 0 and B = 481 are rejected the same way.
    for (std::uint16_t beams : {std::uint16_t{0}, std::uint16_t{481}}) {
        Bytes b = records[1];
        PutU16Be(b, 70, beams);
        const Outcome ob = FeedStream(Concat({b, records[2]}), {});
        ASSERT_EQ(ob.frames.size(), 1u);
        EXPECT_EQ(ob.frames[0], records[2]);
        EXPECT_EQ(SkippedBytes(ob, SkipReason::kBadLength), 3u);
    }
}

TEST(StreamFramer, OverLongAndRuntLengths) {
    const auto records = SampleRecords();
    for (std::uint16_t n :
         {std::uint16_t{2178}, std::uint16_t{0xFFFF}, std::uint16_t{255}, std::uint16_t{0}}) {
        Bytes b = records[0];
        PutU16Be(b, 4, n);
        const Outcome o = FeedStream(Concat({b, records[1]}), {});
        ASSERT_EQ(o.frames.size(), 1u) << n;
        EXPECT_EQ(o.frames[0], records[1]);
        EXPECT_EQ(SkippedBytes(o, SkipReason::kBadLength), 3u);
        EXPECT_EQ(SkippedBytes(o, SkipReason::kGarbage), b.size() - 3);
    }
    // An over-long N is rejected as soon as bytes 4-5 arrive, without waiting for more.
    StreamFramer framer;
    const std::uint8_t head[6] = {'8', '3', 'P', 10, 0x08, 0x82};  // N = 2178
    framer.Push(head);
    const auto ev = framer.Next();
    ASSERT_TRUE(std::holds_alternative<Skipped>(ev));
    EXPECT_EQ(std::get<Skipped>(ev).reason, SkipReason::kBadLength);
    EXPECT_EQ(std::get<Skipped>(ev).bytes, 3u);
}

TEST(StreamFramer, TruncatedEnd) {
    const auto records = SampleRecords();
    Bytes stream = Concat({records[1], records[0]});
    stream.resize(stream.size() - 100);
    const Outcome o = FeedStream(stream, {});
    ASSERT_EQ(o.frames.size(), 1u);
    ASSERT_EQ(o.skipped.size(), 1u);
    EXPECT_EQ(o.skipped[0].reason, SkipReason::kTruncated);
    EXPECT_EQ(o.skipped[0].bytes, records[0].size() - 100);
    EXPECT_EQ(o.skipped[0].offset, records[1].size());
    // A lone partial marker at the end is truncated too.
    Bytes two = records[1];
    Append(two, "83");
    const Outcome p = FeedStream(two, {});
    ASSERT_EQ(p.skipped.size(), 1u);
    EXPECT_EQ(p.skipped[0].reason, SkipReason::kTruncated);
    EXPECT_EQ(p.skipped[0].bytes, 2u);
}

TEST(StreamFramer, UnsupportedRecordsComeOutAsGarbage) {
    Bytes b83 = EncodeRecord83P(MakePing(120, false, 10));
    b83[2] = 'B';
    const Bytes good = EncodeRecord83P(MakePing(120, false, 10));
    const Outcome o = FeedStream(Concat({b83, good}), {});
    ASSERT_EQ(o.frames.size(), 1u);
    EXPECT_EQ(SkippedBytes(o, SkipReason::kGarbage), b83.size());
}

TEST(StreamFramer, SteadyStateKeepsBufferBounded) {
    const Bytes r = EncodeRecord83P(MakePing(480, true, 10));
    StreamFramer framer;
    std::size_t frames = 0;
    for (int i = 0; i < 100; ++i) {
        // Chunks that straddle records.
        for (std::size_t at = 0; at < r.size(); at += 1000) {
            framer.Push(ByteSpan(r.data() + at, std::min<std::size_t>(1000, r.size() - at)));
            while (true) {
                auto ev = framer.Next();
                if (std::holds_alternative<NeedMore>(ev)) break;
                ASSERT_TRUE(std::holds_alternative<Record>(ev));
                ++frames;
            }
            EXPECT_LE(framer.buffered(), kMaxRecordBytes + 2);
        }
    }
    EXPECT_EQ(frames, 100u);
}

TEST(DecodeDatagram, OneRecordPerDatagram) {
    const Bytes r = EncodeRecord83P(MakePing(480, true, 10, 77));
    const auto ok = DecodeDatagram(r);
    ASSERT_TRUE(std::holds_alternative<Ping83P>(ok));
    EXPECT_EQ(std::get<Ping83P>(ok).ping_number, 77u);
    Bytes longer = r;
    longer.push_back(0);
    const auto trailing = DecodeDatagram(longer);
    ASSERT_TRUE(std::holds_alternative<DecodeError>(trailing));
    EXPECT_EQ(std::get<DecodeError>(trailing).kind, DecodeErrorKind::kTrailingBytes);
    EXPECT_EQ(std::get<DecodeError>(trailing).offset, 2176u);
    // rolker's 2048-byte buffer would cut a 2176-byte datagram (§3.2).
    const auto cut = DecodeDatagram(ByteSpan(r.data(), 2048));
    ASSERT_TRUE(std::holds_alternative<DecodeError>(cut));
    EXPECT_EQ(std::get<DecodeError>(cut).kind, DecodeErrorKind::kTruncated);
    EXPECT_EQ(std::get<DecodeError>(cut).offset, 2048u);
    // Two records in one datagram are an error, not two pings.
    const auto two = DecodeDatagram(Concat({EncodeRecord83P(MakePing(120, false, 10)), r}));
    ASSERT_TRUE(std::holds_alternative<DecodeError>(two));
    EXPECT_EQ(std::get<DecodeError>(two).kind, DecodeErrorKind::kTrailingBytes);
    EXPECT_EQ(std::get<DecodeError>(two).offset, 496u);
    // In-place form with a stream memory.
    Ping83P p;
    FloatOrderMemory memory;
    const auto k = DecodeDatagramInto(r, memory, p);
    ASSERT_TRUE(std::holds_alternative<RecordKind>(k));
    EXPECT_EQ(p.intensities.size(), 480u);
    EXPECT_EQ(memory.Get(FloatField::kAltitude), FloatOrder::kBig);
}

}  // namespace
}  // namespace pitmap::protocol::deltat
