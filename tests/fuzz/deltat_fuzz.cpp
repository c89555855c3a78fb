// SPDX-License-Identifier: MIT
// libFuzzer target for the Imagenex Delta T protocol (spec imagenex_deltat.md §1-4):
// StreamFramer and HeadReplyFramer fed in input-driven chunks with the byte-accounting
// invariant checked; framed records decoded, re-encoded and decoded again; the whole input
// also tried as a UDP datagram, an EC frame and a switch data command.
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <variant>
#include <vector>

#include "common/protocol/deltat/ec_frame.hpp"
#include "common/protocol/deltat/head.hpp"
#include "common/protocol/deltat/record83p.hpp"
#include "common/protocol/deltat/stream_framer.hpp"

namespace {

using namespace pitmap;
using namespace pitmap::protocol;
using namespace pitmap::protocol::deltat;

#define FUZZ_CHECK(cond)                                                                  \
    do {                                                                                  \
        if (!(cond)) {                                                                    \
            std::fprintf(stderr, "%s:%d: check failed: %s\n", __FILE__, __LINE__, #cond); \
            std::abort();                                                                 \
        }                                                                                 \
    } while (0)

// Chunk sizes come from the input's first bytes: a tiny xorshift seeded by them.
struct Chunker {
    std::uint32_t state;
    std::size_t Next() {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        // Mostly small chunks, sometimes large ones.
        return (state & 0x100) ? 1 + (state % 2500) : 1 + (state % 17);
    }
};

// Re-encodes a decoded ping and decodes it again; the second encoding must equal the first.
// Floats that were implausible in both orders are zeroed first: their order cannot be
// recovered by the heuristic (spec §4.5), by design.
void CheckPingRoundTrip(const Ping83P& decoded, FloatOrder order) {
    Ping83P canonical = decoded;
    const auto zero_if = [&](FloatField f, float& v) {
        if (canonical.float_implausible_mask & (1u << static_cast<unsigned>(f))) v = 0.0f;
    };
    zero_if(FloatField::kOffsetX, canonical.sonar_offset_m[0]);
    zero_if(FloatField::kOffsetY, canonical.sonar_offset_m[1]);
    zero_if(FloatField::kOffsetZ, canonical.sonar_offset_m[2]);
    zero_if(FloatField::kHeave, canonical.heave_m);
    zero_if(FloatField::kAltitude, canonical.altitude_m);
    zero_if(FloatField::kExternalPitch, canonical.external_pitch_deg);
    zero_if(FloatField::kExternalRoll, canonical.external_roll_deg);
    zero_if(FloatField::kExternalHeading, canonical.external_heading_deg);
    zero_if(FloatField::kScanAngle, canonical.transmit_scan_angle_deg);
    EncodeOptions options;
    options.float_order = order;
    const std::vector<std::uint8_t> first = EncodeRecord83P(canonical, options);
    FUZZ_CHECK(!first.empty());
    FloatOrderMemory memory;
    memory.order.fill(order);
    Ping83P again;
    const auto kind = DecodeRecord83PInto(first, memory, again);
    FUZZ_CHECK(std::holds_alternative<RecordKind>(kind));
    FUZZ_CHECK(std::get<RecordKind>(kind) == RecordKind::kPing);
    FUZZ_CHECK(again.range_counts == canonical.range_counts);
    FUZZ_CHECK(again.intensities == canonical.intensities);
    FUZZ_CHECK(EncodeRecord83P(again, options) == first);
}

void FuzzStreamFramer(ByteSpan input, Chunker chunker) {
    StreamFramer framer;
    FloatOrderMemory memory;
    Ping83P ping;
    std::uint64_t accounted = 0;
    std::size_t at = 0;
    const auto drain = [&] {
        while (true) {
            auto ev = framer.Next();
            if (std::holds_alternative<NeedMore>(ev)) break;
            if (const auto* s = std::get_if<Skipped>(&ev)) {
                FUZZ_CHECK(s->bytes > 0);
                FUZZ_CHECK(s->offset == accounted);
                accounted += s->bytes;
                continue;
            }
            const Record& r = std::get<Record>(ev);
            FUZZ_CHECK(r.offset == accounted);
            FUZZ_CHECK(r.bytes.size() >= kHeaderBytes && r.bytes.size() <= kMaxRecordBytes);
            accounted += r.bytes.size();
            // The framer validated the header: the decoder must accept the record.
            const auto kind = DecodeRecord83PInto(r.bytes, memory, ping);
            FUZZ_CHECK(std::holds_alternative<RecordKind>(kind));
            if (std::get<RecordKind>(kind) == RecordKind::kPing) {
                FUZZ_CHECK(ping.num_beams() == r.layout.num_beams);
                CheckPingRoundTrip(ping, (r.offset & 1) ? FloatOrder::kLittle : FloatOrder::kBig);
            }
        }
        FUZZ_CHECK(framer.buffered() <= kMaxRecordBytes + 2);
    };
    while (at < input.size()) {
        const std::size_t n = std::min(chunker.Next(), input.size() - at);
        framer.Push(input.subspan(at, n));
        at += n;
        drain();
    }
    while (const auto tail = framer.Flush()) {
        FUZZ_CHECK(tail->offset == accounted);
        FUZZ_CHECK(tail->bytes > 0);
        accounted += tail->bytes;
        drain();
    }
    FUZZ_CHECK(framer.buffered() == 0);
    FUZZ_CHECK(accounted == input.size());
    FUZZ_CHECK(framer.bytes_pushed() == input.size());
}

void FuzzHeadFramer(ByteSpan input, Chunker chunker) {
    HeadReplyFramer framer;
    std::uint64_t accounted = 0;
    std::size_t at = 0;
    const auto drain = [&] {
        while (true) {
            auto ev = framer.Next();
            if (std::holds_alternative<NeedMore>(ev)) break;
            if (const auto* s = std::get_if<Skipped>(&ev)) {
                FUZZ_CHECK(s->bytes > 0);
                FUZZ_CHECK(s->offset == accounted);
                accounted += s->bytes;
                continue;
            }
            const HeadFrame& f = std::get<HeadFrame>(ev);
            FUZZ_CHECK(f.offset == accounted);
            FUZZ_CHECK(f.bytes.size() == kHeadReplyBytes);
            accounted += f.bytes.size();
            const auto d = DecodeHeadReply(f.bytes);
            FUZZ_CHECK(std::holds_alternative<HeadReply>(d));
            const std::vector<std::uint8_t> again = EncodeHeadReply(std::get<HeadReply>(d));
            FUZZ_CHECK(again.size() == f.bytes.size());
            FUZZ_CHECK(std::equal(again.begin(), again.end(), f.bytes.begin()));
        }
        FUZZ_CHECK(framer.buffered() < kHeadReplyBytes);
    };
    while (at < input.size()) {
        const std::size_t n = std::min(chunker.Next(), input.size() - at);
        framer.Push(input.subspan(at, n));
        at += n;
        drain();
    }
    while (const auto tail = framer.Flush()) {
        FUZZ_CHECK(tail->offset == accounted);
        FUZZ_CHECK(tail->bytes > 0);
        accounted += tail->bytes;
        drain();
    }
    FUZZ_CHECK(framer.buffered() == 0);
    FUZZ_CHECK(accounted == input.size());
}

void FuzzSingleFrames(ByteSpan input) {
    FloatOrderMemory memory;
    const auto d = DecodeDatagram(input, memory);
    if (const auto* p = std::get_if<Ping83P>(&d)) {
        FUZZ_CHECK(p->total_bytes == input.size());
        CheckPingRoundTrip(*p, FloatOrder::kBig);
        CheckPingRoundTrip(*p, FloatOrder::kLittle);
    }
    const auto ec = DecodeEcFrame(input);
    if (const auto* f = std::get_if<EcFrame>(&ec)) {
        const auto bytes = EncodeEcFrame(*f);
        FUZZ_CHECK(bytes.size() == kEcFrameBytes);
        const auto again = DecodeEcFrame(bytes);
        FUZZ_CHECK(std::holds_alternative<EcFrame>(again));
        FUZZ_CHECK(EncodeEcFrame(std::get<EcFrame>(again)) == bytes);
    }
    const auto cmd = DecodeSwitchCommand(input);
    if (const auto* c = std::get_if<SwitchCommand>(&cmd)) {
        const auto bytes = EncodeSwitchCommand(*c);
        FUZZ_CHECK(bytes.size() == kSwitchCommandBytes);
        const auto again = DecodeSwitchCommand(bytes);
        FUZZ_CHECK(std::holds_alternative<SwitchCommand>(again));
        FUZZ_CHECK(EncodeSwitchCommand(std::get<SwitchCommand>(again)) == bytes);
    }
    const auto head = DecodeHeadReply(input);
    if (const auto* h = std::get_if<HeadReply>(&head)) {
        const auto bytes = EncodeHeadReply(*h);
        FUZZ_CHECK(bytes.size() == input.size());
        FUZZ_CHECK(std::equal(bytes.begin(), bytes.end(), input.begin()));
    }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const ByteSpan all(data, size);
    FuzzSingleFrames(all);
    // The first 2 bytes seed the chunking; the rest is the stream (seeds stay valid streams
    // when prefixed by two bytes).
    if (size < 2) return 0;
    Chunker chunker{static_cast<std::uint32_t>(data[0] | data[1] << 8) * 2654435761u | 1u};
    const ByteSpan stream = all.subspan(2);
    FuzzStreamFramer(stream, chunker);
    FuzzHeadFramer(stream, chunker);
    FuzzSingleFrames(stream);
    return 0;
}
