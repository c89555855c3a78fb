// SPDX-License-Identifier: MIT
// NovAtel OEM message encoder (shared/specs/novatel_oem.md §2-§6): the inverse of decoder.hpp,
// so simulators and receiver emulators speak the receiver's bytes.
//
// Binary: long (28-byte) or short (12-byte) header chosen by `header.kind` (kShortBinary or
// kShortAscii -> short, anything else -> long), the id from `header.message_id` (it must be one
// of the ids of that struct, e.g. 42 or 1429 for BestPos), body as in §6, CRC-32 appended.
// The long header's length byte is always 28; bit 7 of the message type is set from
// `header.is_response`. Response encodes as a binary response (ULong id + text).
// ASCII: "#NAMEA,<header>;<fields>*crc\r\n" (or "%NAMEA,week,seconds;..." for a short header)
// for BESTPOS, BESTGNSSPOS, BESTVEL, BESTGNSSVEL, INSPVA, INSPVAS, INSPVAX, TIME, HEADING2;
// responses as "<text\r\n" (abbreviated) or "#NAMER,...;text*crc\r\n"; prompts as "[port]".
// Numbers are printed with the receiver's usual decimals (e.g. 11 for latitude in BESTPOSA),
// enums by name (by number when the value has no name).
//
// Each function appends to `out` and returns false, appending nothing, when the message cannot
// be encoded that way. No allocation beyond `out`'s growth (Reserve it once for steady state).
#pragma once

#include <cstdint>
#include <vector>

#include "common/protocol/novatel/messages.hpp"

namespace pitmap::protocol::novatel {

bool EncodeBinary(const Message& message, std::vector<std::uint8_t>& out);
bool EncodeAscii(const Message& message, std::vector<std::uint8_t>& out);

// Per-type overloads, avoiding the copy into a Message.
bool EncodeBinary(const BestPos& m, std::vector<std::uint8_t>& out);
bool EncodeBinary(const BestVel& m, std::vector<std::uint8_t>& out);
bool EncodeBinary(const InsPva& m, std::vector<std::uint8_t>& out);
bool EncodeBinary(const InsPvaX& m, std::vector<std::uint8_t>& out);
bool EncodeBinary(const InsAtt& m, std::vector<std::uint8_t>& out);
bool EncodeBinary(const InsAttX& m, std::vector<std::uint8_t>& out);
bool EncodeBinary(const CorrImuData& m, std::vector<std::uint8_t>& out);
bool EncodeBinary(const CorrImuS& m, std::vector<std::uint8_t>& out);
bool EncodeBinary(const RawImu& m, std::vector<std::uint8_t>& out);
bool EncodeBinary(const Time& m, std::vector<std::uint8_t>& out);
bool EncodeBinary(const Heading2& m, std::vector<std::uint8_t>& out);
bool EncodeBinary(const MarkTime& m, std::vector<std::uint8_t>& out);
bool EncodeBinary(const InsStdDev& m, std::vector<std::uint8_t>& out);
bool EncodeBinary(const InsConfig& m, std::vector<std::uint8_t>& out);
bool EncodeBinary(const RxStatus& m, std::vector<std::uint8_t>& out);
bool EncodeBinary(const Response& m, std::vector<std::uint8_t>& out);

// The long-header port byte's ASCII name: 0x20 "COM1", 0x3E "COM1_30", ...; "" if ambiguous.
std::string PortNameFromAddress(std::uint8_t port_address);

}  // namespace pitmap::protocol::novatel
