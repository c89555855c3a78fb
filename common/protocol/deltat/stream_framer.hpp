// SPDX-License-Identifier: MIT
// Framing of 83P records concatenated in a TCP stream or a .83P file, and the one-record UDP
// datagram decoder.
//
// Reference: shared/specs/imagenex_deltat.md §1.1 (a .83P file is the records concatenated,
// no file header), §3.2 (one UDP datagram per ping), §4.1-4.2 (resync on `83P`, validate N
// against B and byte 117 before trusting it), §2.3 (MB-System comment records, N = 256).
//
// Contract (common/protocol/framing.hpp): every pushed byte comes out exactly once, inside a
// Record or counted in a Skipped. A candidate whose header fails validation is skipped as
// kBadLength (its 3 marker bytes; the marker cannot overlap itself) and the scan resumes
// after it. Records carry no checksum, so a complete candidate that holds another valid
// header inside it is accepted only when the next `83P` marker follows it (a false header must
// not swallow the real records behind it); it waits for those 3 bytes, and is skipped as
// kBadLength when they are something else. Bytes that start no marker are kGarbage. 83B/83M
// records are not framed: they come out as garbage (log the raw bytes to keep them).
// Memory: bytes retained after Next() returned NeedMore are at most kMaxRecordBytes + 2 (a
// record that waits for the marker after it). The buffer grows once to the largest Push plus
// one record and is reused: no allocation per record in steady state. Drain Next() until
// NeedMore before the next Push.
// Not thread safe: one framer per stream.
#pragma once

#include <cstdint>
#include <optional>
#include <variant>
#include <vector>

#include "common/byte_io.hpp"
#include "common/protocol/deltat/record83p.hpp"
#include "common/protocol/framing.hpp"

namespace pitmap::protocol::deltat {

// One framed 83P record (a ping or an MB-System comment): a view into the framer's buffer,
// valid until the next Push/Next call. Decode it with DecodeRecord83PInto.
struct Record {
    ByteSpan bytes;
    std::uint64_t offset = 0;  // stream offset of the record's first byte
    Layout83P layout;          // what the validated header says
};

class StreamFramer {
public:
    StreamFramer();

    // Appends bytes delivered by the transport or read from a file.
    void Push(ByteSpan bytes);
    // The next event: a record, skipped bytes, or NeedMore when nothing complete is buffered.
    std::variant<NeedMore, Skipped, Record> Next();
    // End of stream: gives up the candidate record that waits for more bytes (its marker and
    // the garbage after it) as kTruncated, or nullopt when nothing is buffered. The bytes it had
    // buffered behind are framed again: call after Next() returned NeedMore, drain Next(), and
    // repeat until Flush() returns nullopt.
    std::optional<Skipped> Flush();
    // For a transport's maximum wait: like Flush() (as kStale), but only when a complete record
    // is buffered behind the waiting candidate (proof that it is false); nullopt otherwise.
    std::optional<Skipped> Expire();

    std::uint64_t bytes_pushed() const { return pushed_; }
    std::size_t buffered() const { return tail_ - head_; }

private:
    Skipped Skip(SkipReason reason, std::size_t n);
    std::optional<Skipped> GiveUpCandidate(SkipReason reason);

    std::vector<std::uint8_t> buffer_;
    std::size_t head_ = 0;        // first unconsumed byte
    std::size_t tail_ = 0;        // one past the last valid byte
    std::uint64_t consumed_ = 0;  // stream offset of buffer_[head_]
    std::uint64_t pushed_ = 0;
};

// One UDP datagram = one record (§3.2): decodes it with DecodeRecord83PInto rules, reporting
// missing bytes as kTruncated and extra bytes as kTrailingBytes.
std::variant<RecordKind, DecodeError> DecodeDatagramInto(ByteSpan datagram,
                                                         FloatOrderMemory& memory,
                                                         Ping83P& out);
Decoded83P DecodeDatagram(ByteSpan datagram, FloatOrderMemory& memory);
Decoded83P DecodeDatagram(ByteSpan datagram);

}  // namespace pitmap::protocol::deltat
