// SPDX-License-Identifier: MIT
// Imagenex Delta T raw head session over TCP port 4040: the 27-byte switch data command
// (host -> head) and the 1033-byte return packet (head -> host), with an incremental framer
// for logged or live head traffic. The 1000 data bytes are opaque: their mapping to beams is
// not publicly documented (spec §0 [U]), so nothing here produces soundings.
//
// Reference: shared/specs/imagenex_deltat.md §3.1 (byte tables; [C] where LSTS DUNE and ACFR
// agree, [1]/[U] where noted per field).
// Framer contract: common/protocol/framing.hpp. Sync = `I`, `U`|`V`, `X`, head id; fixed
// length 1033; byte 1032 must be 0xFC, else the candidate's 3 marker bytes are skipped as
// kBadTerminator and the scan resumes. Bytes retained after NeedMore < 1033; the buffer is
// reused (no allocation per packet in steady state). Not thread safe.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <variant>
#include <vector>

#include "common/byte_io.hpp"
#include "common/protocol/deltat/messages.hpp"
#include "common/protocol/framing.hpp"

namespace pitmap::protocol::deltat {

inline constexpr std::size_t kSwitchCommandBytes = 27;
inline constexpr std::size_t kHeadReplyBytes = 1033;
inline constexpr std::size_t kHeadReplyHeaderBytes = 32;
inline constexpr std::size_t kHeadReplyDataBytes = 1000;
inline constexpr std::uint8_t kDefaultHeadId = 0x10;
inline constexpr std::uint8_t kHeadReplyTerminator = 0xFC;

// Switch data command, 27 bytes (§3.1). Fixed bytes (0xFE 0x44 header, zeros, 0xFD) are not
// stored. Values are in physical units where the wire has a scale.
struct SwitchCommand {
    std::uint8_t head_id = kDefaultHeadId;        // byte 2
    std::uint8_t range_m = 50;                    // byte 3: 5,10,20,30,40,50,60,80,100
    std::uint8_t range_offset = 0;                // byte 4 [1]
    std::uint16_t nadir_offset_raw = 0;           // bytes 5-6 BE, 65536 = 360 deg [1]
    std::uint8_t start_gain_db = 10;              // byte 8 (0-20)
    std::uint8_t logf = 1;                        // byte 9, meaning [U]
    std::uint8_t absorption_centi_db_per_m = 10;  // byte 10, 0.01 dB/m
    std::uint8_t agc_threshold = 120;             // byte 11 (10-250) [1]
    std::uint8_t packet_number = 0;               // byte 13: 0 .. packets()-1
    std::uint16_t pulse_length_us = 300;          // byte 14 x 10 us
    std::uint16_t data_points = 8000;             // byte 19 x 1000: 8000 or 16000
    std::uint8_t data_bits = 8;                   // byte 20
    std::uint8_t orientation_request = 0x80;      // byte 21: 0x80 asks for orientation [1]
    std::uint8_t run_mode = 0;                    // byte 22: bit4 = AGC [1]
    std::uint16_t switch_delay_ms = 0;            // byte 24 x 2 ms (0-510)
    std::uint8_t frequency_code = 86;             // byte 25: kHz = 5 * code - 170 (derived)

    std::uint8_t packets() const { return static_cast<std::uint8_t>(data_points / 1000); }
    int frequency_khz() const { return 5 * frequency_code - 170; }
    double nadir_offset_deg() const { return nadir_offset_raw * 360.0 / 65536.0; }
    bool agc() const { return (run_mode & 0x10) != 0; }
};

// Decodes exactly 27 bytes: kBadMarker without 0xFE 0x44, kBadTerminator without 0xFD at 26,
// kBadValue for data points other than 8/16 (byte 19) or a packet number >= packets (13).
std::variant<SwitchCommand, DecodeError> DecodeSwitchCommand(ByteSpan bytes);
// Appends 27 bytes; false (nothing appended) if pulse length is not a multiple of 10 us up to
// 2550, the switch delay not even up to 510 ms, data points not 8000/16000, or the packet
// number out of range.
bool EncodeSwitchCommand(const SwitchCommand& command, std::vector<std::uint8_t>& out);
std::vector<std::uint8_t> EncodeSwitchCommand(const SwitchCommand& command);

// Return packet, 1033 bytes (§3.1). Undocumented bytes are kept raw so a packet re-encodes
// byte for byte.
struct HeadReply {
    std::uint8_t mode = 'U';                     // byte 1: 'U' 8000 points, 'V' 16000 points
    std::uint8_t head_id = kDefaultHeadId;       // byte 3
    std::uint8_t serial_status = 0;              // byte 4
    std::uint8_t packet_number = 0;              // byte 5: echo of command byte 13 [C]
    std::uint8_t firmware_version = 0;           // byte 6
    std::uint8_t range_m = 0;                    // byte 7
    std::array<std::uint8_t, 2> bytes_8_9{};     // undocumented
    std::uint16_t data_bytes_be = 1000;          // bytes 10-11 read big-endian; byte order [U]
    std::uint8_t byte_12 = 0;                    // undocumented
    std::uint8_t orientation_type = 0;           // byte 13: non-zero = valid (packet 0) [1]
    std::int16_t pitch_raw = 0;                  // bytes 14-15 LE, 65536 = 360 deg [1]
    std::int16_t roll_raw = 0;                   // bytes 16-17 LE [1]
    std::int16_t heading_raw = 0;                // bytes 18-19 LE [1]
    std::array<std::uint8_t, 12> bytes_20_31{};  // undocumented [U]
    std::array<std::uint8_t, kHeadReplyDataBytes> data{};  // raw echo data, opaque

    // 1000 in either byte order (the order is [U]); otherwise the raw big-endian value.
    std::uint16_t data_bytes() const {
        const auto swapped =
            static_cast<std::uint16_t>((data_bytes_be >> 8) | (data_bytes_be << 8));
        return swapped == kHeadReplyDataBytes ? swapped : data_bytes_be;
    }
    bool orientation_valid() const { return orientation_type != 0; }
    double pitch_deg() const { return pitch_raw * 360.0 / 65536.0; }
    double roll_deg() const { return roll_raw * 360.0 / 65536.0; }
    double heading_deg() const { return heading_raw * 360.0 / 65536.0; }
};

// Decodes exactly 1033 bytes: kBadMarker without `I`,`U|V`,`X`; kBadTerminator without 0xFC.
std::variant<HeadReply, DecodeError> DecodeHeadReply(ByteSpan bytes);
// Appends 1033 bytes; false (nothing appended) if mode is neither 'U' nor 'V'.
bool EncodeHeadReply(const HeadReply& reply, std::vector<std::uint8_t>& out);
std::vector<std::uint8_t> EncodeHeadReply(const HeadReply& reply);

// One framed return packet: a view into the framer's buffer, valid until the next Push/Next.
struct HeadFrame {
    ByteSpan bytes;
    std::uint64_t offset = 0;  // stream offset of the first byte
};

class HeadReplyFramer {
public:
    explicit HeadReplyFramer(std::uint8_t head_id = kDefaultHeadId);

    void Push(ByteSpan bytes);
    std::variant<NeedMore, Skipped, HeadFrame> Next();
    // End of stream: gives up the packet that waits for more bytes (its sync byte and the bytes
    // after it that start no packet) as kTruncated, or nullopt when nothing is buffered. Drain
    // Next() and repeat until it returns nullopt.
    std::optional<Skipped> Flush();

    std::uint64_t bytes_pushed() const { return pushed_; }
    std::size_t buffered() const { return tail_ - head_; }

private:
    bool MatchesSyncPrefix(const std::uint8_t* p, std::size_t n) const;
    Skipped Skip(SkipReason reason, std::size_t n);

    std::uint8_t head_id_;
    std::vector<std::uint8_t> buffer_;
    std::size_t head_ = 0;
    std::size_t tail_ = 0;
    std::uint64_t consumed_ = 0;
    std::uint64_t pushed_ = 0;
};

}  // namespace pitmap::protocol::deltat
