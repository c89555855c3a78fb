// SPDX-License-Identifier: MIT
// 83P stream framer. Spec: shared/specs/imagenex_deltat.md §1.1, §3.2, §4.1-4.2.
#include "common/protocol/deltat/stream_framer.hpp"

#include <cstring>

namespace pitmap::protocol::deltat {

StreamFramer::StreamFramer() : buffer_(2 * kMaxRecordBytes) {}

void StreamFramer::Push(ByteSpan bytes) {
    if (bytes.empty()) return;
    pushed_ += bytes.size();
    if (head_ > 0) {
        // Retained bytes are a partial record (< kMaxRecordBytes after a drain): cheap move.
        std::memmove(buffer_.data(), buffer_.data() + head_, tail_ - head_);
        tail_ -= head_;
        head_ = 0;
    }
    if (tail_ + bytes.size() > buffer_.size()) buffer_.resize(tail_ + bytes.size());
    std::memcpy(buffer_.data() + tail_, bytes.data(), bytes.size());
    tail_ += bytes.size();
}

Skipped StreamFramer::Skip(SkipReason reason, std::size_t n) {
    const Skipped s{reason, n, consumed_};
    head_ += n;
    consumed_ += n;
    return s;
}

std::variant<NeedMore, Skipped, Record> StreamFramer::Next() {
    const std::size_t avail = tail_ - head_;
    if (avail == 0) return NeedMore{};
    const std::uint8_t* p = buffer_.data() + head_;
    const bool marker_prefix =
        p[0] == kMarker0 && (avail < 2 || p[1] == kMarker1) && (avail < 3 || p[2] == kMarker2);
    if (!marker_prefix) {
        // Garbage up to the next '8' that could start a marker (possibly cut by the end).
        std::size_t i = 1;
        while (i < avail) {
            const void* hit = std::memchr(p + i, kMarker0, avail - i);
            if (hit == nullptr) {
                i = avail;
                break;
            }
            i = static_cast<std::size_t>(static_cast<const std::uint8_t*>(hit) - p);
            if ((i + 1 >= avail || p[i + 1] == kMarker1) &&
                (i + 2 >= avail || p[i + 2] == kMarker2)) {
                break;
            }
            ++i;
        }
        return Skip(SkipReason::kGarbage, i);
    }
    if (avail < 3) return NeedMore{};
    const auto validated = ValidateHeader83P(ByteSpan(p, avail));
    if (const auto* e = std::get_if<DecodeError>(&validated)) {
        if (e->kind == DecodeErrorKind::kTruncated) return NeedMore{};
        // `83P` cannot overlap itself, so no candidate starts inside the marker.
        return Skip(SkipReason::kBadLength, 3);
    }
    const Layout83P& layout = std::get<Layout83P>(validated);
    if (avail < layout.total_bytes) return NeedMore{};
    const Record record{ByteSpan(p, layout.total_bytes), consumed_, layout};
    head_ += layout.total_bytes;
    consumed_ += layout.total_bytes;
    return record;
}

std::optional<Skipped> StreamFramer::Flush() {
    const std::size_t avail = tail_ - head_;
    if (avail == 0) return std::nullopt;
    return Skip(SkipReason::kTruncated, avail);
}

std::variant<RecordKind, DecodeError> DecodeDatagramInto(ByteSpan datagram,
                                                         FloatOrderMemory& memory, Ping83P& out) {
    // DecodeRecord83PInto already requires exactly N bytes.
    return DecodeRecord83PInto(datagram, memory, out);
}

Decoded83P DecodeDatagram(ByteSpan datagram, FloatOrderMemory& memory) {
    return DecodeRecord83P(datagram, memory);
}

Decoded83P DecodeDatagram(ByteSpan datagram) { return DecodeRecord83P(datagram); }

}  // namespace pitmap::protocol::deltat
