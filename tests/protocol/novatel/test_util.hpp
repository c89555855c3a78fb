// SPDX-License-Identifier: MIT
// Helpers shared by the NovAtel protocol tests: file loading, hex parsing, hand-built frames
// (independent of encoder.cpp) and a framer driver that checks the byte-accounting invariant.
#pragma once

// GCC 12 at -O3 reports -Wnull-dereference / -Warray-bounds false positives on the
// std::vector<uint8_t> element writes these tests are made of (GCC bugs 105329, 106238).
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wnull-dereference"
#pragma GCC diagnostic ignored "-Warray-bounds"
#pragma GCC diagnostic ignored "-Wstringop-overflow"
#endif

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "common/protocol/novatel/crc32.hpp"
#include "common/protocol/novatel/framer.hpp"

namespace pitmap::protocol::novatel::testing {

using Bytes = std::vector<std::uint8_t>;

inline Bytes ReadFile(const std::string& name) {
    std::ifstream in(std::string(PITMAP_TEST_DATA_DIR) + "/novatel/" + name, std::ios::binary);
    EXPECT_TRUE(in.good()) << name;
    return Bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

inline Bytes FromHex(std::string_view hex) {
    Bytes out;
    int hi = -1;
    for (char c : hex) {
        int v = -1;
        if (c >= '0' && c <= '9') v = c - '0';
        if (c >= 'a' && c <= 'f') v = c - 'a' + 10;
        if (c >= 'A' && c <= 'F') v = c - 'A' + 10;
        if (v < 0) continue;
        if (hi < 0) {
            hi = v;
        } else {
            out.push_back(static_cast<std::uint8_t>(hi * 16 + v));
            hi = -1;
        }
    }
    return out;
}

inline Bytes FromText(std::string_view text) {
    return Bytes(text.begin(), text.end());
}

inline void AppendCrc(Bytes& b) {
    const std::uint32_t crc = Crc32(b);
    for (int i = 0; i < 4; ++i) b.push_back(static_cast<std::uint8_t>(crc >> (8 * i)));
}

// Writes the CRC of b[0, size-4) into the last 4 bytes of b.
inline void StoreCrc(Bytes& b) {
    const std::size_t n = b.size() - 4;
    const std::uint32_t crc = Crc32(ByteSpan(b.data(), n));
    for (std::size_t i = 0; i < 4; ++i) b[n + i] = static_cast<std::uint8_t>(crc >> (8 * i));
}

// A long-header binary frame with the given id and body, CRC appended.
inline Bytes LongFrame(std::uint16_t id,
                       const Bytes& body,
                       std::uint8_t message_type = 0,
                       std::uint8_t sync1 = 0x44) {
    // Sized once: growing the vector trips a GCC 12 -Warray-bounds false positive.
    Bytes b(28 + body.size() + 4, 0);
    b[0] = 0xAA;
    b[1] = sync1;
    b[2] = 0x12;
    b[3] = 28;
    b[4] = static_cast<std::uint8_t>(id);
    b[5] = static_cast<std::uint8_t>(id >> 8);
    b[6] = message_type;
    b[7] = 0x20;
    b[8] = static_cast<std::uint8_t>(body.size());
    b[9] = static_cast<std::uint8_t>(body.size() >> 8);
    b[13] = 180;
    std::copy(body.begin(), body.end(), b.begin() + 28);
    StoreCrc(b);
    return b;
}

inline Bytes ShortFrame(std::uint16_t id, const Bytes& body) {
    Bytes b(12 + body.size() + 4, 0);
    b[0] = 0xAA;
    b[1] = 0x44;
    b[2] = 0x13;
    b[3] = static_cast<std::uint8_t>(body.size());
    b[4] = static_cast<std::uint8_t>(id);
    b[5] = static_cast<std::uint8_t>(id >> 8);
    std::copy(body.begin(), body.end(), b.begin() + 12);
    StoreCrc(b);
    return b;
}

// "#BODY*crc\r\n" with the CRC computed over BODY.
inline Bytes AsciiLine(char sync, std::string_view body) {
    char crc[9];
    std::snprintf(crc, sizeof crc, "%08x", Crc32(FromText(body)));
    return FromText(std::string(1, sync) + std::string(body) + "*" + crc + "\r\n");
}

// A false long-binary sync, `AA 44 12 1C`, whose length field claims a frame of
// `claimed_total` bytes, padded to a 28-byte header with `fill` (no frame start byte).
inline Bytes FalseLongHeader(std::uint16_t claimed_total = 30000, std::uint8_t fill = 0x11) {
    Bytes h(28, fill);
    h[0] = 0xAA;
    h[1] = 0x44;
    h[2] = 0x12;
    h[3] = 0x1C;
    const auto message_length = static_cast<std::uint16_t>(claimed_total - 28 - 4);
    h[8] = static_cast<std::uint8_t>(message_length & 0xFF);
    h[9] = static_cast<std::uint8_t>(message_length >> 8);
    return h;
}

struct FrameCopy {
    FrameKind kind;
    std::int32_t message_id;
    Bytes bytes;
    std::uint64_t offset;
    bool operator==(const FrameCopy&) const = default;
};

struct Events {
    std::vector<FrameCopy> frames;
    std::vector<Skipped> skips;
    SkipCounters counters;
    std::uint64_t frame_bytes = 0;
    // Every event in order: frames as index >= 0, skips as ~index.
    std::vector<long> order;
};

inline bool operator==(const Skipped& a, const Skipped& b) {
    return a.reason == b.reason && a.bytes == b.bytes && a.offset == b.offset;
}

// Calls Next() until NeedMore, recording events and checking that offsets are contiguous.
inline void Drain(Framer& framer, Events& ev, std::uint64_t& next_offset) {
    while (true) {
        auto r = framer.Next();
        if (std::holds_alternative<NeedMore>(r)) return;
        if (auto* s = std::get_if<Skipped>(&r)) {
            EXPECT_EQ(s->offset, next_offset);
            EXPECT_GT(s->bytes, 0u);
            next_offset = s->offset + s->bytes;
            ev.counters.Add(*s);
            ev.order.push_back(~static_cast<long>(ev.skips.size()));
            ev.skips.push_back(*s);
            continue;
        }
        const Frame& f = std::get<Frame>(r);
        EXPECT_EQ(f.offset, next_offset);
        next_offset = f.offset + f.bytes.size();
        ev.frame_bytes += f.bytes.size();
        ev.order.push_back(static_cast<long>(ev.frames.size()));
        ev.frames.push_back(
            {f.kind, f.message_id, Bytes(f.bytes.begin(), f.bytes.end()), f.offset});
    }
}

// Frames `data` pushed in chunks of the given sizes (cycled), then flushes until empty. Checks that
// every byte is accounted for exactly once.
inline Events FrameAll(const Bytes& data, const std::vector<std::size_t>& chunks = {}) {
    Framer framer;
    Events ev;
    std::uint64_t next = 0;
    std::size_t pos = 0;
    std::size_t k = 0;
    while (pos < data.size()) {
        std::size_t n = chunks.empty() ? data.size() : chunks[k++ % chunks.size()];
        n = std::max<std::size_t>(1, std::min(n, data.size() - pos));
        framer.Push(ByteSpan(data.data() + pos, n));
        pos += n;
        Drain(framer, ev, next);
    }
    // End of input: the waiting candidate gives up its sync, the rest is framed again.
    while (auto tail = framer.Flush()) {
        EXPECT_EQ(tail->offset, next);
        next += tail->bytes;
        ev.counters.Add(*tail);
        ev.order.push_back(~static_cast<long>(ev.skips.size()));
        ev.skips.push_back(*tail);
        Drain(framer, ev, next);
    }
    EXPECT_EQ(next, data.size());
    EXPECT_EQ(ev.frame_bytes + ev.counters.TotalBytes(), data.size());
    EXPECT_EQ(framer.buffered(), 0u);
    return ev;
}

}  // namespace pitmap::protocol::novatel::testing
