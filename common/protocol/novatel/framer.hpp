// SPDX-License-Identifier: MIT
// NovAtel OEM4..OEM7 byte-stream framer (shared/specs/novatel_oem.md §1-§5, robust-parser
// checklist §9; OEM7 firmware 7.x, OEM6, OEMV/OEM4 "AA 44 12" family; OEM3 "AA 44 11" is not
// framed and comes out as garbage).
//
// One receiver port carries freely interleaved framings (§1):
//   AA 44 12  long binary (28+ byte header, CRC-32)       -> FrameKind::kLongBinary
//   AA 44 13  short binary (12-byte header, CRC-32)       -> FrameKind::kShortBinary
//   AA 45 12  proprietary binary, framed like long binary  -> FrameKind::kProprietary (kept raw)
//   #...*xxxxxxxx CR LF  ASCII log or response (CRC-32)    -> FrameKind::kAscii
//   %...*xxxxxxxx CR LF  short ASCII log (CRC-32)          -> FrameKind::kShortAscii
//   <... CR LF    abbreviated ASCII response or log line  -> FrameKind::kAbbreviated
//   [COM1] etc.   port prompt, no terminator               -> FrameKind::kPrompt
//   $...*hh CR LF NMEA 0183 (XOR checksum)                 -> FrameKind::kNmea
//
// Resynchronisation (§9 items 1-5): a candidate that fails (bad CRC, impossible length, broken
// text) gives up its first byte only and the scan restarts at the next byte, so a frame hidden
// behind a false sync or behind injected garbage is still found. Text candidates may contain
// printable ASCII only (0x20..0x7E, plus the final CR LF), so they can never swallow a binary
// sync (0xAA) or binary payload. Binary lengths are checked before they are trusted: header
// length >= 28, total <= 32768 bytes (long), 12 + length + 4 <= 271 (short).
//
// Byte accounting: every pushed byte comes out exactly once, inside a Frame or inside a
// Skipped (common/protocol/framing.hpp). CR/LF between frames (e.g. before "<OK") is garbage.
//
// Partial frames: the framer never times out (it has no clock). A candidate whose length field
// points past the buffered data waits for more bytes, up to 32768 bytes for a long frame; if it
// was a false sync, its CRC fails once they have come and the scan resumes one byte after it, so
// nothing behind it is lost, only delayed. Two calls shorten that wait:
//   - Flush(), at the end of the stream, gives up the waiting candidate (its first byte and the
//     bytes after it that cannot start a frame) as SkipReason::kTruncated;
//   - Expire(), for a transport's maximum wait (§9 item 4), does the same as kStale, but only
//     when a complete checksummed frame is buffered behind the candidate (which proves it
//     false). A real frame cut by a pause keeps waiting for its rest.
// Both leave the bytes behind the candidate buffered: a false sync whose length field claims
// 30 000 bytes does not take the real frames behind it along. So both are called in a loop,
// draining Next() in between:
//   for (;;) { <Next() until NeedMore>; auto s = framer.Flush(); if (!s) break; <count *s>; }
// Flush() ends with nothing buffered. Both leave the framer ready for more bytes.
//
// Memory: one buffer holding the unconsumed tail (< 32768 bytes once Next() returns NeedMore)
// plus the bytes of one Push. Its capacity is kept, so steady-state framing allocates nothing.
// Not thread safe: one framer per byte stream.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string_view>
#include <variant>
#include <vector>

#include "common/byte_io.hpp"
#include "common/protocol/framing.hpp"

namespace pitmap::protocol::novatel {

inline constexpr std::size_t kLongHeaderMinLength = 28;    // §2
inline constexpr std::size_t kShortHeaderLength = 12;      // §3
inline constexpr std::size_t kCrcLength = 4;               // §4
inline constexpr std::size_t kMaxLongFrameLength = 32768;  // §2, §9 item 5
inline constexpr std::size_t kMaxShortFrameLength = 271;   // 12 + 255 + 4
inline constexpr std::size_t kMaxAsciiFrameLength = 32768;
inline constexpr std::size_t kMaxAbbreviatedLineLength = 4096;
inline constexpr std::size_t kMaxNmeaLength = 256;  // NMEA says 82; NovAtel's own are longer
inline constexpr std::size_t kMaxPromptLength = 24;

enum class FrameKind : std::uint8_t {
    kLongBinary = 0,
    kShortBinary,
    kProprietary,
    kAscii,
    kShortAscii,
    kAbbreviated,
    kPrompt,
    kNmea,
};

std::string_view ToString(FrameKind kind);

// One complete, checksum-valid frame. `bytes` points into the framer's buffer and stays valid
// only until the next Push() or Next() call on that framer.
struct Frame {
    FrameKind kind = FrameKind::kLongBinary;
    // Binary: the header's message id. ASCII/short ASCII: the id of the log name (without its
    // A/R suffix) when the name is known (MessageIdFromName), else -1. Other kinds: -1.
    std::int32_t message_id = -1;
    ByteSpan bytes;            // the whole frame, sync to CRC / terminator inclusive
    std::uint64_t offset = 0;  // stream offset of bytes[0] (bytes pushed before it)
};

// Incremental framer; see the file comment for the contract.
class Framer {
public:
    Framer();

    // Appends bytes delivered by the transport. Invalidates the span of the last Frame.
    void Push(ByteSpan bytes);
    // The next event: a frame, bytes skipped with a reason, or NeedMore when nothing complete is
    // buffered. Call until NeedMore after every Push.
    std::variant<NeedMore, Skipped, Frame> Next();
    // End of stream: gives up the candidate frame that waits for more bytes (kTruncated) and
    // returns what it skipped, or nullopt if nothing is buffered. Call after Next() has
    // returned NeedMore, then drain Next() again, until Flush() returns nullopt.
    std::optional<Skipped> Flush();
    // For a transport's maximum wait: like Flush() (as kStale), but only when a complete
    // checksummed frame is buffered behind the waiting candidate; nullopt otherwise.
    std::optional<Skipped> Expire();

    // Bytes pushed so far (the stream offset of the next pushed byte).
    std::uint64_t bytes_pushed() const { return base_offset_ + buffer_.size(); }
    // Bytes buffered but not yet handed out.
    std::size_t buffered() const { return buffer_.size() - start_; }

private:
    enum class Outcome : std::uint8_t { kFrame, kNeedMore, kNotAFrame, kBadCrc, kBadLength };
    struct Attempt {
        Outcome outcome = Outcome::kNotAFrame;
        FrameKind kind = FrameKind::kLongBinary;
        std::size_t length = 0;
        std::int32_t message_id = -1;
    };

    Attempt TryAt(std::size_t pos) const;
    Attempt TryBinary(std::size_t pos) const;
    Attempt TryCrcText(std::size_t pos, FrameKind kind) const;
    Attempt TryAbbreviated(std::size_t pos) const;
    Attempt TryPrompt(std::size_t pos) const;
    Attempt TryNmea(std::size_t pos) const;
    Skipped Consume(std::size_t n, SkipReason reason);
    std::optional<Skipped> GiveUpCandidate(SkipReason reason);
    bool ChecksummedFrameBehind() const;

    std::vector<std::uint8_t> buffer_;
    std::size_t start_ = 0;          // first unconsumed byte in buffer_
    std::uint64_t base_offset_ = 0;  // stream offset of buffer_[0]
};

// Message id of a log or command name as used in ASCII headers and LOG commands, without the
// A/B/R suffix ("BESTPOS" -> 42). nullopt for names not in the table.
std::optional<std::uint16_t> MessageIdFromName(std::string_view name);
// Inverse of MessageIdFromName ("" when unknown).
std::string_view MessageNameFromId(std::uint16_t id);

}  // namespace pitmap::protocol::novatel
