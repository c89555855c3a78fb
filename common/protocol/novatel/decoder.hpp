// SPDX-License-Identifier: MIT
// NovAtel OEM message decoder (shared/specs/novatel_oem.md §2-§6; OEM7 firmware 7.x, OEM6,
// OEMV). Pure: a Frame from the Framer in, a plain struct out (common/protocol/novatel/
// messages.hpp).
//
// Binary logs are dispatched through a table keyed by message id holding each log's minimum
// body length (the runt check): a shorter body is DecodeError{kRunt}; a longer one is decoded
// and the extra bytes ignored (newer firmware appends fields). Frames with the response bit set
// (§5, §9 item 7) decode as Response whatever their id. ASCII logs (#NAMEA / %NAMEA) are parsed
// field by field into the same structs for BESTPOS, BESTGNSSPOS, BESTVEL, BESTGNSSVEL, INSPVA,
// INSPVAS, INSPVAX, TIME and HEADING2; "#NAMER" lines and "<OK"/"<ERROR:" lines are Responses.
// Anything else that framed correctly is Unsupported (counted by callers, not an error).
// Thread safe (no state). Never throws, whatever the bytes.
#pragma once

#include <variant>

#include "common/protocol/novatel/framer.hpp"
#include "common/protocol/novatel/messages.hpp"

namespace pitmap::protocol::novatel {

using DecodeResult = MessageOr<Unsupported, DecodeError>;

DecodeResult Decode(const Frame& frame);

// Minimum body length of a binary log id the decoder supports; nullopt if unsupported.
std::optional<std::size_t> MinimumBodyLength(std::uint16_t message_id);

// True when the result holds one of the Message alternatives.
inline bool IsMessage(const DecodeResult& r) {
    return !std::holds_alternative<Unsupported>(r) && !std::holds_alternative<DecodeError>(r);
}

// The Message alternative of a result (precondition: IsMessage(r)).
Message ToMessage(DecodeResult r);

}  // namespace pitmap::protocol::novatel
