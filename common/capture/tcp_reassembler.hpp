// SPDX-License-Identifier: MIT
// TCP reassembly of one direction of one connection, by sequence number.
//
// Segments are given in capture (arrival) order. The reassembler behaves like a receiver with
// an unbounded reorder buffer: bytes at the expected sequence number are delivered, earlier
// bytes are duplicates (retransmissions, overlaps, keep-alives) and are dropped and counted,
// later bytes wait until the hole before them is filled. At Finish() the holes that were never
// filled are reported as gaps and the waiting bytes are delivered after them.
//
// Sequence numbers wrap at 2^32: each one is unwrapped against the previous one seen in the
// same direction, so a stream may carry more than 4 GiB.
// Not thread safe.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <vector>

#include "common/byte_io.hpp"

namespace pitmap::capture {

// [offset, ...) of the reassembled stream became readable at utime (host capture time of the
// segment that completed it). Offsets increase strictly.
struct StreamChunk {
    std::size_t offset = 0;
    std::int64_t utime = 0;  // Unix microseconds (capture timestamp)
};

// A hole in the stream: `missing_bytes` bytes were never captured before stream offset
// `offset` (the bytes after the hole follow directly in TcpStream::bytes).
struct StreamGap {
    std::size_t offset = 0;
    std::uint64_t missing_bytes = 0;
};

// Counters of one reassembled direction.
struct TcpStreamStats {
    std::uint64_t packets = 0;                 // every TCP packet of this direction
    std::uint64_t payload_segments = 0;        // packets carrying payload
    std::uint64_t payload_bytes = 0;           // payload bytes as captured, duplicates included
    std::uint64_t retransmitted_segments = 0;  // segments resending bytes that had arrived
    std::uint64_t retransmitted_bytes = 0;     // bytes dropped as duplicates
    std::uint64_t overlapping_segments = 0;    // retransmitted segments that also carried new
                                               // bytes (included in retransmitted_segments)
    std::uint64_t out_of_order_segments = 0;   // segments that arrived ahead of a hole
    std::uint64_t gaps = 0;                    // holes never filled
    std::uint64_t gap_bytes = 0;               // bytes missing in those holes
    bool syn_seen = false;
    bool fin_seen = false;
    bool rst_seen = false;
};

class TcpReassembler {
public:
    // One TCP segment: its sequence number, flags and payload (may be empty).
    void AddSegment(
        std::int64_t utime, std::uint32_t seq, bool syn, bool fin, bool rst, ByteSpan payload);

    // Ends the stream: fills the outputs below. Call once, after the last AddSegment.
    void Finish();

    const std::vector<std::uint8_t>& bytes() const { return bytes_; }
    std::vector<std::uint8_t>& mutable_bytes() { return bytes_; }
    const std::vector<StreamChunk>& chunks() const { return chunks_; }
    const std::vector<StreamGap>& stream_gaps() const { return gaps_; }
    const TcpStreamStats& stats() const { return stats_; }
    std::int64_t first_utime() const { return first_utime_; }
    std::int64_t last_utime() const { return last_utime_; }

private:
    struct Pending {
        std::int64_t utime = 0;
        std::vector<std::uint8_t> bytes;
    };

    std::int64_t Unwrap(std::uint32_t seq);
    // Appends [start, start + data.size()) at the expected position, trimming what is old.
    void Deliver(std::int64_t start, ByteSpan data, std::int64_t utime);
    void DrainPending();

    std::vector<std::uint8_t> bytes_;
    std::vector<StreamChunk> chunks_;
    std::vector<StreamGap> gaps_;
    TcpStreamStats stats_;
    std::int64_t first_utime_ = 0;
    std::int64_t last_utime_ = 0;

    bool have_seq_ = false;
    std::uint32_t last_seq_ = 0;  // raw value of the last sequence number unwrapped
    std::int64_t last_abs_ = 0;   // its unwrapped value
    bool have_syn_ = false;
    std::int64_t syn_abs_ = 0;          // unwrapped sequence number of the SYN
    std::int64_t next_ = 0;             // unwrapped sequence number of the next byte expected
    std::int64_t last_fill_utime_ = 0;  // capture time of the segment that filled the last hole
    std::map<std::int64_t, Pending> pending_;  // segments ahead of a hole, by start
    // The stream start is known only at the end when no SYN was captured (it is the lowest
    // sequence number seen), so segments are held in arrival order and replayed by Finish().
    struct Held {
        std::int64_t utime = 0;
        std::int64_t start = 0;
        std::vector<std::uint8_t> bytes;
    };
    std::vector<Held> held_;
    bool finished_ = false;
};

}  // namespace pitmap::capture
