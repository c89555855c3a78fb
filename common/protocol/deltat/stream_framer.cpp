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

namespace {

// End of the garbage run that starts at p[0]: the next position from `from` on where `83P` (or
// a prefix of it cut by the end of the buffer) could start, or avail.
std::size_t GarbageRunEnd(const std::uint8_t* p, std::size_t avail, std::size_t from) {
    std::size_t i = from;
    while (i < avail) {
        const void* hit = std::memchr(p + i, kMarker0, avail - i);
        if (hit == nullptr) return avail;
        i = static_cast<std::size_t>(static_cast<const std::uint8_t*>(hit) - p);
        if ((i + 1 >= avail || p[i + 1] == kMarker1) && (i + 2 >= avail || p[i + 2] == kMarker2)) {
            return i;
        }
        ++i;
    }
    return avail;
}

// True when a `83P` marker inside p[3, total) starts a header that validates, or one that
// could not be validated yet with the bytes buffered.
bool HoldsAnotherHeader(const std::uint8_t* p, std::size_t total, std::size_t avail) {
    static constexpr std::uint8_t kMarker[3] = {kMarker0, kMarker1, kMarker2};
    std::size_t i = 3;
    while (i + 3 <= total) {
        const void* hit = ::memmem(p + i, total - i, kMarker, 3);
        if (hit == nullptr) return false;
        i = static_cast<std::size_t>(static_cast<const std::uint8_t*>(hit) - p);
        const auto v = ValidateHeader83P(ByteSpan(p + i, avail - i));
        if (std::holds_alternative<Layout83P>(v)) return true;
        if (std::get<DecodeError>(v).kind == DecodeErrorKind::kTruncated) return true;
        i += 3;
    }
    return false;
}

}  // namespace

std::variant<NeedMore, Skipped, Record> StreamFramer::Next() {
    const std::size_t avail = tail_ - head_;
    if (avail == 0) return NeedMore{};
    const std::uint8_t* p = buffer_.data() + head_;
    const bool marker_prefix =
        p[0] == kMarker0 && (avail < 2 || p[1] == kMarker1) && (avail < 3 || p[2] == kMarker2);
    if (!marker_prefix) {
        // Garbage up to the next '8' that could start a marker (possibly cut by the end).
        return Skip(SkipReason::kGarbage, GarbageRunEnd(p, avail, 1));
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
    // 83P has no checksum. A candidate that holds another header which validates may be a
    // false header swallowing real records: it is trusted only when the next marker follows
    // it; otherwise only its marker is skipped and the records inside are framed.
    // The common case, a record followed by the next marker, costs a 3-byte compare; the scan
    // for an inner header runs only for the last record buffered or one not followed by a
    // marker.
    const std::size_t end = layout.total_bytes;
    const bool marker_follows =
        avail >= end + 3 && p[end] == kMarker0 && p[end + 1] == kMarker1 && p[end + 2] == kMarker2;
    if (!marker_follows && HoldsAnotherHeader(p, end, avail)) {
        if (avail < end + 3) return NeedMore{};
        return Skip(SkipReason::kBadLength, 3);
    }
    const Record record{ByteSpan(p, layout.total_bytes), consumed_, layout};
    head_ += layout.total_bytes;
    consumed_ += layout.total_bytes;
    return record;
}

std::optional<Skipped> StreamFramer::GiveUpCandidate(SkipReason reason) {
    const std::size_t avail = tail_ - head_;
    if (avail == 0) return std::nullopt;
    // Only the waiting candidate's marker goes (with the garbage after it); what it had
    // buffered behind is scanned again, so a false header cannot take real records with it.
    return Skip(reason, GarbageRunEnd(buffer_.data() + head_, avail, 1));
}

std::optional<Skipped> StreamFramer::Flush() {
    return GiveUpCandidate(SkipReason::kTruncated);
}

std::optional<Skipped> StreamFramer::Expire() {
    // Only a candidate with a complete record behind it is given up (it cannot be real then); a
    // real record cut by a pause keeps waiting for its rest.
    const std::size_t avail = tail_ - head_;
    const std::uint8_t* p = buffer_.data() + head_;
    static constexpr std::uint8_t kMarker[3] = {kMarker0, kMarker1, kMarker2};
    for (std::size_t i = 1; i + 3 <= avail;) {
        const void* hit = ::memmem(p + i, avail - i, kMarker, 3);
        if (hit == nullptr) break;
        i = static_cast<std::size_t>(static_cast<const std::uint8_t*>(hit) - p);
        const auto v = ValidateHeader83P(ByteSpan(p + i, avail - i));
        if (const auto* layout = std::get_if<Layout83P>(&v);
            layout != nullptr && i + layout->total_bytes <= avail) {
            return GiveUpCandidate(SkipReason::kStale);
        }
        i += 3;
    }
    return std::nullopt;
}

std::variant<RecordKind, DecodeError> DecodeDatagramInto(ByteSpan datagram,
                                                         FloatOrderMemory& memory,
                                                         Ping83P& out) {
    // DecodeRecord83PInto already requires exactly N bytes.
    return DecodeRecord83PInto(datagram, memory, out);
}

Decoded83P DecodeDatagram(ByteSpan datagram, FloatOrderMemory& memory) {
    return DecodeRecord83P(datagram, memory);
}

Decoded83P DecodeDatagram(ByteSpan datagram) {
    return DecodeRecord83P(datagram);
}

}  // namespace pitmap::protocol::deltat
