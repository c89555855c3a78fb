// SPDX-License-Identifier: MIT
// Vocabulary shared by every framer in common/protocol: why bytes were skipped, and counters.
//
// The framing contract (after NovAtel EDIE's framer, gpsd's packet layer):
//   framer.Push(bytes);                 // append what a transport delivered
//   while (true) {
//     auto ev = framer.Next();          // std::variant<NeedMore, Skipped, <Vendor>Frame>
//     if (NeedMore) break;              // nothing complete buffered
//     if (Skipped)  count it;           // bytes that are not (part of) a valid frame
//     if (Frame)    decode it;          // a span into the framer's buffer: valid until the
//   }                                   // next Push/Next call
//   while (auto s = framer.Flush()) {   // end of stream: the candidate that waits for more
//     count *s; drain Next() again;     // bytes gives up its sync only, and what it had
//   }                                   // buffered behind is framed again
// Every byte pushed comes out exactly once, either inside a frame or counted in a Skipped:
// nothing is dropped silently. Buffers are bounded by the longest legal frame; no allocation
// per frame in steady state.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string_view>

namespace pitmap::protocol {

enum class SkipReason : std::uint8_t {
    kGarbage = 0,    // bytes before a sync pattern / between frames that start no frame
    kBadCrc,         // a complete candidate frame whose CRC/checksum failed (only its sync byte
                     // is skipped: the framer rescans from the next byte)
    kBadLength,      // a header whose length field is impossible (runt or over-long)
    kBadTerminator,  // a fixed-length frame without its terminator byte
    kTruncated,      // the stream ended (Flush) inside a frame
    kStale,          // a partial frame abandoned because no more bytes came in time
    kCount
};

inline constexpr std::size_t kNumSkipReasons = static_cast<std::size_t>(SkipReason::kCount);

constexpr std::string_view ToString(SkipReason r) {
    switch (r) {
        case SkipReason::kGarbage:
            return "garbage";
        case SkipReason::kBadCrc:
            return "bad_crc";
        case SkipReason::kBadLength:
            return "bad_length";
        case SkipReason::kBadTerminator:
            return "bad_terminator";
        case SkipReason::kTruncated:
            return "truncated";
        case SkipReason::kStale:
            return "stale";
        case SkipReason::kCount:
            break;
    }
    return "unknown";
}

// The framer has no complete frame buffered: push more bytes.
struct NeedMore {};

// `bytes` bytes starting at stream offset `offset` were skipped for `reason`.
struct Skipped {
    SkipReason reason = SkipReason::kGarbage;
    std::size_t bytes = 0;
    std::uint64_t offset = 0;  // bytes pushed before the first skipped byte
};

// Bytes skipped by reason, plus the count of Skipped events of each reason.
struct SkipCounters {
    std::array<std::uint64_t, kNumSkipReasons> bytes{};
    std::array<std::uint64_t, kNumSkipReasons> events{};

    void Add(const Skipped& s) {
        bytes[static_cast<std::size_t>(s.reason)] += s.bytes;
        events[static_cast<std::size_t>(s.reason)] += 1;
    }
    std::uint64_t Bytes(SkipReason r) const { return bytes[static_cast<std::size_t>(r)]; }
    std::uint64_t Events(SkipReason r) const { return events[static_cast<std::size_t>(r)]; }
    std::uint64_t TotalBytes() const {
        std::uint64_t t = 0;
        for (auto b : bytes) t += b;
        return t;
    }
};

}  // namespace pitmap::protocol
