// SPDX-License-Identifier: MIT
#include "common/capture/tcp_reassembler.hpp"

#include <algorithm>

#include "common/result.hpp"

namespace pitmap::capture {

std::int64_t TcpReassembler::Unwrap(std::uint32_t seq) {
    if (!have_seq_) {
        have_seq_ = true;
        last_seq_ = seq;
        last_abs_ = static_cast<std::int64_t>(seq);
        return last_abs_;
    }
    // RFC 793 sequence space arithmetic: the signed 32-bit difference picks the nearer of the
    // two ways round the circle.
    const auto delta = static_cast<std::int32_t>(seq - last_seq_);
    last_seq_ = seq;
    last_abs_ += delta;
    return last_abs_;
}

void TcpReassembler::AddSegment(
    std::int64_t utime, std::uint32_t seq, bool syn, bool fin, bool rst, ByteSpan payload) {
    PITMAP_CHECK(!finished_, "AddSegment after Finish");
    if (stats_.packets == 0) first_utime_ = utime;
    last_utime_ = std::max(last_utime_, utime);
    ++stats_.packets;
    std::int64_t start = Unwrap(seq);
    if (syn) {
        // The first SYN fixes the initial sequence number; a retransmitted SYN changes nothing.
        if (!have_syn_) {
            have_syn_ = true;
            stats_.syn_seen = true;
            syn_abs_ = start;
        }
        start += 1;  // the SYN occupies one sequence number before the data
    }
    stats_.fin_seen = stats_.fin_seen || fin;
    stats_.rst_seen = stats_.rst_seen || rst;
    if (payload.empty()) return;
    ++stats_.payload_segments;
    stats_.payload_bytes += payload.size();
    held_.push_back(Held{utime, start, std::vector<std::uint8_t>(payload.begin(), payload.end())});
}

void TcpReassembler::Deliver(std::int64_t start, ByteSpan data, std::int64_t utime) {
    // A segment with bytes that had already arrived is a retransmission (as Wireshark counts
    // them), whether it resends them alone or together with new bytes.
    if (start < next_) {
        const auto old = static_cast<std::size_t>(next_ - start);
        ++stats_.retransmitted_segments;
        stats_.retransmitted_bytes += std::min(old, data.size());
        if (old >= data.size()) return;
        ++stats_.overlapping_segments;
        data = data.subspan(old);
    }
    chunks_.push_back(StreamChunk{bytes_.size(), utime});
    bytes_.insert(bytes_.end(), data.begin(), data.end());
    next_ += static_cast<std::int64_t>(data.size());
}

void TcpReassembler::DrainPending() {
    while (!pending_.empty() && pending_.begin()->first <= next_) {
        auto node = pending_.extract(pending_.begin());
        Deliver(node.key(), node.mapped().bytes, last_fill_utime_);
    }
}

void TcpReassembler::Finish() {
    PITMAP_CHECK(!finished_, "Finish called twice");
    finished_ = true;
    if (held_.empty()) return;
    if (have_syn_) {
        next_ = syn_abs_ + 1;
    } else {
        next_ = held_.front().start;
        for (const auto& h : held_) next_ = std::min(next_, h.start);
    }

    for (auto& h : held_) {
        if (h.start > next_) {
            // Ahead of a hole: wait for it to be filled. The same start again is a
            // retransmission of a waiting segment; the longer copy is kept.
            auto it = pending_.find(h.start);
            if (it == pending_.end()) {
                ++stats_.out_of_order_segments;
                pending_.emplace(h.start, Pending{h.utime, std::move(h.bytes)});
                continue;
            }
            ++stats_.retransmitted_segments;
            const std::size_t kept = it->second.bytes.size();
            stats_.retransmitted_bytes += std::min(kept, h.bytes.size());
            if (h.bytes.size() > kept) {
                ++stats_.overlapping_segments;
                it->second.bytes = std::move(h.bytes);
            }
            continue;
        }
        last_fill_utime_ = h.utime;
        Deliver(h.start, h.bytes, h.utime);
        DrainPending();
    }
    held_.clear();

    // Holes nobody filled: report them and deliver what lies beyond.
    while (!pending_.empty()) {
        const auto& [start, pending] = *pending_.begin();
        if (start > next_) {
            const auto missing = static_cast<std::uint64_t>(start - next_);
            gaps_.push_back(StreamGap{bytes_.size(), missing});
            ++stats_.gaps;
            stats_.gap_bytes += missing;
            next_ = start;
        }
        last_fill_utime_ = pending.utime;
        DrainPending();
    }
}

}  // namespace pitmap::capture
