// SPDX-License-Identifier: MIT
// libFuzzer target for the NovAtel framer + decoder + encoder (common/protocol/novatel).
// The first bytes choose chunk sizes; the rest is pushed in those chunks. Every frame is
// decoded; decoded messages are re-encoded (binary, and ASCII where supported) and the
// re-encoding must frame and decode back to the same message. The byte-accounting invariant
// (every pushed byte exactly once in a frame or a Skipped, offsets contiguous) is asserted.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <variant>
#include <vector>

#include "common/protocol/novatel/decoder.hpp"
#include "common/protocol/novatel/encoder.hpp"
#include "common/protocol/novatel/framer.hpp"

namespace nv = pitmap::protocol::novatel;
using pitmap::ByteSpan;

namespace {

void Check(bool condition) {
    if (!condition) std::abort();
}

// Frames `bytes` completely and returns the single decoded message, if exactly one frame.
bool DecodeSingle(const std::vector<std::uint8_t>& bytes, nv::DecodeResult& out) {
    nv::Framer framer;
    framer.Push(bytes);
    int frames = 0;
    while (true) {
        auto ev = framer.Next();
        if (std::holds_alternative<pitmap::protocol::NeedMore>(ev)) break;
        if (auto* f = std::get_if<nv::Frame>(&ev)) {
            ++frames;
            out = nv::Decode(*f);
        } else {
            return false;
        }
    }
    return frames == 1 && !framer.Flush().has_value();
}

void Reencode(const nv::Message& m, nv::FrameKind source) {
    std::vector<std::uint8_t> out;
    if (nv::EncodeBinary(m, out)) {
        nv::DecodeResult r;
        Check(DecodeSingle(out, r));
        Check(nv::IsMessage(r));
        // From binary: exact. From ASCII: the binary header has no port name, so same type.
        const bool from_binary =
            source == nv::FrameKind::kLongBinary || source == nv::FrameKind::kShortBinary;
        Check(from_binary ? nv::ToMessage(r) == m : nv::ToMessage(r).index() == m.index());
    }
    out.clear();
    if (nv::EncodeAscii(m, out)) {
        // ASCII quantises numbers; it must at least frame and decode to the same type.
        nv::DecodeResult r;
        Check(DecodeSingle(out, r));
        Check(nv::IsMessage(r));
        Check(nv::ToMessage(r).index() == m.index());
    }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    if (size < 2) return 0;
    const std::size_t num_chunk_sizes = 1 + data[0] % 8;
    if (size < 1 + num_chunk_sizes) return 0;
    std::size_t chunk_sizes[8];
    for (std::size_t i = 0; i < num_chunk_sizes; ++i) chunk_sizes[i] = 1 + data[1 + i] * 4u;
    const std::uint8_t* stream = data + 1 + num_chunk_sizes;
    const std::size_t stream_size = size - 1 - num_chunk_sizes;

    nv::Framer framer;
    std::uint64_t accounted = 0;
    std::size_t pos = 0;
    std::size_t k = 0;
    const auto drain = [&]() {
        while (true) {
            auto ev = framer.Next();
            if (std::holds_alternative<pitmap::protocol::NeedMore>(ev)) return;
            if (auto* s = std::get_if<pitmap::protocol::Skipped>(&ev)) {
                Check(s->offset == accounted && s->bytes > 0);
                accounted += s->bytes;
                continue;
            }
            const nv::Frame& f = std::get<nv::Frame>(ev);
            Check(f.offset == accounted && !f.bytes.empty());
            Check(f.bytes.size() <= nv::kMaxLongFrameLength);
            accounted += f.bytes.size();
            const nv::DecodeResult r = nv::Decode(f);
            if (nv::IsMessage(r)) Reencode(nv::ToMessage(r), f.kind);
        }
    };
    while (pos < stream_size) {
        const std::size_t n = std::min(chunk_sizes[k++ % num_chunk_sizes], stream_size - pos);
        framer.Push(ByteSpan(stream + pos, n));
        pos += n;
        drain();
        Check(framer.buffered() <= nv::kMaxLongFrameLength + n);
    }
    while (auto tail = framer.Flush()) {
        Check(tail->offset == accounted);
        Check(tail->bytes > 0);
        accounted += tail->bytes;
        drain();
    }
    Check(framer.buffered() == 0);
    Check(accounted == stream_size);
    Check(framer.bytes_pushed() == stream_size);
    return 0;
}
