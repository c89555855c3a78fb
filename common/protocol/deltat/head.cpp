// SPDX-License-Identifier: MIT
// Raw head session (switch data command, return packet, framer).
// Spec: shared/specs/imagenex_deltat.md §3.1.
#include "common/protocol/deltat/head.hpp"

#include <cstring>

namespace pitmap::protocol::deltat {
namespace {

constexpr std::uint8_t kCommandHeader0 = 0xFE;
constexpr std::uint8_t kCommandHeader1 = 0x44;
constexpr std::uint8_t kCommandTerminator = 0xFD;
// `I`, `U|V`, `X` cannot reappear at offsets 1-2 of a candidate: a rejected candidate skips
// these 3 bytes and the head-id byte is rescanned.
constexpr std::size_t kSyncSkip = 3;

bool IsModeByte(std::uint8_t b) {
    return b == 'U' || b == 'V';
}

}  // namespace

std::variant<SwitchCommand, DecodeError> DecodeSwitchCommand(ByteSpan bytes) {
    if (bytes.size() < kSwitchCommandBytes) {
        return DecodeError{DecodeErrorKind::kTruncated, bytes.size(), "command shorter than 27"};
    }
    if (bytes.size() > kSwitchCommandBytes) {
        return DecodeError{
            DecodeErrorKind::kTrailingBytes, kSwitchCommandBytes, "command longer than 27"};
    }
    ByteReader r(bytes);
    if (r.U8() != kCommandHeader0 || r.U8() != kCommandHeader1) {
        return DecodeError{DecodeErrorKind::kBadMarker, 0, "no 0xFE 0x44 header"};
    }
    if (bytes[26] != kCommandTerminator) {
        return DecodeError{DecodeErrorKind::kBadTerminator, 26, "no 0xFD terminator"};
    }
    SwitchCommand c;
    c.head_id = r.U8();
    c.range_m = r.U8();
    c.range_offset = r.U8();
    c.nadir_offset_raw = r.U16Be();
    r.U8();  // 7
    c.start_gain_db = r.U8();
    c.logf = r.U8();
    c.absorption_centi_db_per_m = r.U8();
    c.agc_threshold = r.U8();
    r.U8();  // 12
    c.packet_number = r.U8();
    c.pulse_length_us = static_cast<std::uint16_t>(r.U8() * 10);
    r.Skip(4);  // 15-18
    const std::uint8_t points_k = r.U8();
    if (points_k != 8 && points_k != 16) {
        return DecodeError{DecodeErrorKind::kBadValue, 19, "data points not 8000/16000"};
    }
    c.data_points = static_cast<std::uint16_t>(points_k * 1000);
    if (c.packet_number >= c.packets()) {
        return DecodeError{DecodeErrorKind::kBadValue, 13, "packet number >= packets"};
    }
    c.data_bits = r.U8();
    c.orientation_request = r.U8();
    c.run_mode = r.U8();
    r.U8();  // 23
    c.switch_delay_ms = static_cast<std::uint16_t>(r.U8() * 2);
    c.frequency_code = r.U8();
    return c;
}

bool EncodeSwitchCommand(const SwitchCommand& c, std::vector<std::uint8_t>& out) {
    if (c.pulse_length_us % 10 != 0 || c.pulse_length_us > 2550 || c.switch_delay_ms % 2 != 0 ||
        c.switch_delay_ms > 510 || (c.data_points != 8000 && c.data_points != 16000) ||
        c.packet_number >= c.packets()) {
        return false;
    }
    out.reserve(out.size() + kSwitchCommandBytes);
    ByteWriter w(out);
    w.U8(kCommandHeader0);                                    // 0
    w.U8(kCommandHeader1);                                    // 1
    w.U8(c.head_id);                                          // 2
    w.U8(c.range_m);                                          // 3
    w.U8(c.range_offset);                                     // 4
    w.U16Be(c.nadir_offset_raw);                              // 5-6
    w.U8(0);                                                  // 7
    w.U8(c.start_gain_db);                                    // 8
    w.U8(c.logf);                                             // 9
    w.U8(c.absorption_centi_db_per_m);                        // 10
    w.U8(c.agc_threshold);                                    // 11
    w.U8(0);                                                  // 12
    w.U8(c.packet_number);                                    // 13
    w.U8(static_cast<std::uint8_t>(c.pulse_length_us / 10));  // 14
    w.Zeros(4);                                               // 15-18
    w.U8(c.packets());                                        // 19
    w.U8(c.data_bits);                                        // 20
    w.U8(c.orientation_request);                              // 21
    w.U8(c.run_mode);                                         // 22
    w.U8(0);                                                  // 23
    w.U8(static_cast<std::uint8_t>(c.switch_delay_ms / 2));   // 24
    w.U8(c.frequency_code);                                   // 25
    w.U8(kCommandTerminator);                                 // 26
    return true;
}

std::vector<std::uint8_t> EncodeSwitchCommand(const SwitchCommand& command) {
    std::vector<std::uint8_t> out;
    if (!EncodeSwitchCommand(command, out)) out.clear();
    return out;
}

std::variant<HeadReply, DecodeError> DecodeHeadReply(ByteSpan bytes) {
    if (bytes.size() < kHeadReplyBytes) {
        return DecodeError{DecodeErrorKind::kTruncated, bytes.size(), "reply shorter than 1033"};
    }
    if (bytes.size() > kHeadReplyBytes) {
        return DecodeError{
            DecodeErrorKind::kTrailingBytes, kHeadReplyBytes, "reply longer than 1033"};
    }
    if (bytes[0] != 'I' || !IsModeByte(bytes[1]) || bytes[2] != 'X') {
        return DecodeError{DecodeErrorKind::kBadMarker, 0, "no I?X sync"};
    }
    if (bytes[kHeadReplyBytes - 1] != kHeadReplyTerminator) {
        return DecodeError{
            DecodeErrorKind::kBadTerminator, kHeadReplyBytes - 1, "no 0xFC terminator"};
    }
    HeadReply h;
    ByteReader r(bytes);
    r.Seek(1);
    h.mode = r.U8();
    r.U8();  // 'X'
    h.head_id = r.U8();
    h.serial_status = r.U8();
    h.packet_number = r.U8();
    h.firmware_version = r.U8();
    h.range_m = r.U8();
    h.bytes_8_9[0] = r.U8();
    h.bytes_8_9[1] = r.U8();
    h.data_bytes_be = r.U16Be();
    h.byte_12 = r.U8();
    h.orientation_type = r.U8();
    h.pitch_raw = r.I16Le();
    h.roll_raw = r.I16Le();
    h.heading_raw = r.I16Le();
    for (auto& b : h.bytes_20_31) b = r.U8();
    const ByteSpan data = r.Bytes(kHeadReplyDataBytes);
    if (data.size() == kHeadReplyDataBytes) std::memcpy(h.data.data(), data.data(), data.size());
    return h;
}

bool EncodeHeadReply(const HeadReply& h, std::vector<std::uint8_t>& out) {
    if (!IsModeByte(h.mode)) return false;
    out.reserve(out.size() + kHeadReplyBytes);
    ByteWriter w(out);
    w.U8('I');
    w.U8(h.mode);
    w.U8('X');
    w.U8(h.head_id);
    w.U8(h.serial_status);
    w.U8(h.packet_number);
    w.U8(h.firmware_version);
    w.U8(h.range_m);
    w.U8(h.bytes_8_9[0]);
    w.U8(h.bytes_8_9[1]);
    w.U16Be(h.data_bytes_be);
    w.U8(h.byte_12);
    w.U8(h.orientation_type);
    w.I16Le(h.pitch_raw);
    w.I16Le(h.roll_raw);
    w.I16Le(h.heading_raw);
    for (auto b : h.bytes_20_31) w.U8(b);
    w.Bytes(ByteSpan(h.data.data(), h.data.size()));
    w.U8(kHeadReplyTerminator);
    return true;
}

std::vector<std::uint8_t> EncodeHeadReply(const HeadReply& reply) {
    std::vector<std::uint8_t> out;
    if (!EncodeHeadReply(reply, out)) out.clear();
    return out;
}

HeadReplyFramer::HeadReplyFramer(std::uint8_t head_id)
    : head_id_(head_id), buffer_(2 * kHeadReplyBytes) {}

void HeadReplyFramer::Push(ByteSpan bytes) {
    if (bytes.empty()) return;
    pushed_ += bytes.size();
    if (head_ > 0) {
        std::memmove(buffer_.data(), buffer_.data() + head_, tail_ - head_);
        tail_ -= head_;
        head_ = 0;
    }
    if (tail_ + bytes.size() > buffer_.size()) buffer_.resize(tail_ + bytes.size());
    std::memcpy(buffer_.data() + tail_, bytes.data(), bytes.size());
    tail_ += bytes.size();
}

bool HeadReplyFramer::MatchesSyncPrefix(const std::uint8_t* p, std::size_t n) const {
    return p[0] == 'I' && (n < 2 || IsModeByte(p[1])) && (n < 3 || p[2] == 'X') &&
           (n < 4 || p[3] == head_id_);
}

Skipped HeadReplyFramer::Skip(SkipReason reason, std::size_t n) {
    const Skipped s{reason, n, consumed_};
    head_ += n;
    consumed_ += n;
    return s;
}

std::variant<NeedMore, Skipped, HeadFrame> HeadReplyFramer::Next() {
    const std::size_t avail = tail_ - head_;
    if (avail == 0) return NeedMore{};
    const std::uint8_t* p = buffer_.data() + head_;
    if (!MatchesSyncPrefix(p, avail)) {
        std::size_t i = 1;
        while (i < avail) {
            const void* hit = std::memchr(p + i, 'I', avail - i);
            if (hit == nullptr) {
                i = avail;
                break;
            }
            i = static_cast<std::size_t>(static_cast<const std::uint8_t*>(hit) - p);
            if (MatchesSyncPrefix(p + i, avail - i)) break;
            ++i;
        }
        return Skip(SkipReason::kGarbage, i);
    }
    if (avail < kHeadReplyBytes) return NeedMore{};
    if (p[kHeadReplyBytes - 1] != kHeadReplyTerminator) {
        return Skip(SkipReason::kBadTerminator, kSyncSkip);
    }
    const HeadFrame frame{ByteSpan(p, kHeadReplyBytes), consumed_};
    head_ += kHeadReplyBytes;
    consumed_ += kHeadReplyBytes;
    return frame;
}

std::optional<Skipped> HeadReplyFramer::Flush() {
    const std::size_t avail = tail_ - head_;
    if (avail == 0) return std::nullopt;
    // Only the waiting packet's sync byte goes, with the bytes after it that start no packet;
    // what it had buffered behind is framed again by Next().
    const std::uint8_t* p = buffer_.data() + head_;
    std::size_t i = 1;
    while (i < avail && !MatchesSyncPrefix(p + i, avail - i)) ++i;
    return Skip(SkipReason::kTruncated, i);
}

}  // namespace pitmap::protocol::deltat
