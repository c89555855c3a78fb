// SPDX-License-Identifier: MIT
// Imagenex Delta T 83P profile-point record: header validation, decoder and encoder.
//
// Reference: shared/specs/imagenex_deltat.md §1.1-1.5 (layout, scaling, geometry), §2.3
// (MB-System comment records) and §4 items 2-15 (validation rules). Vendor document: Imagenex
// "83P Profile Point Output" of 16 Mar 2010, v1.00 and v1.10.
//
// Failure model: every input is data. Decoders return a DecodeError value for anything that
// is not a valid record; nothing throws, nothing reads out of bounds. Implausible values in a
// well-formed record are passed on (the stage filters them).
// Thread safety: free functions are reentrant; a FloatOrderMemory belongs to one stream.
#pragma once

#include <cstdint>
#include <optional>
#include <string_view>
#include <variant>
#include <vector>

#include "common/byte_io.hpp"
#include "common/protocol/deltat/messages.hpp"

namespace pitmap::protocol::deltat {

// What the length fields of a header say (§1.3, §4.2).
struct Layout83P {
    std::uint8_t format_version = 0;
    std::uint16_t total_bytes = 0;        // N
    std::uint16_t num_beams = 0;          // B (0 for a comment record)
    bool comment = false;                 // MB-System comment record (§2.3)
    bool intensity = false;               // intensities follow the ranges
    bool intensity_flag_ignored = false;  // byte 117 = 1 with N = 256+2B (MB-System writer)
};

// Checks the marker and the length fields of a record prefix: N in 256..2176, B in 1..480,
// N = 256+2B, or 256+4B when byte 117 = 1 (v1.10). N = 256+2B with byte 117 = 1 is accepted
// as "no intensity" (§4.2). Versions 1..9 are read with the v1.00 layout, >= 10 as v1.10
// (§1.2). Needs kMinBytesToValidate bytes (8 for a comment record); fewer -> kTruncated.
std::variant<Layout83P, DecodeError> ValidateHeader83P(ByteSpan prefix);

// The kinds of a successfully decoded 83P record.
enum class RecordKind : std::uint8_t { kPing = 0, kComment };

// Decodes exactly one record: `record` must be exactly N bytes (shorter -> kTruncated, longer
// -> kTrailingBytes). Decodes into `out`, reusing its vectors (no allocation once their
// capacity reached B); on kComment or an error `out` is unspecified. `memory` carries the
// per-stream float byte-order choices (§4.5).
std::variant<RecordKind, DecodeError> DecodeRecord83PInto(ByteSpan record,
                                                          FloatOrderMemory& memory,
                                                          Ping83P& out);

using Decoded83P = std::variant<Ping83P, Comment83P, DecodeError>;
// Convenience form of DecodeRecord83PInto (allocates the beam vectors).
Decoded83P DecodeRecord83P(ByteSpan record, FloatOrderMemory& memory);
Decoded83P DecodeRecord83P(ByteSpan record);  // with a fresh FloatOrderMemory

struct EncodeOptions {
    FloatOrder float_order = FloatOrder::kBig;  // kUnknown is written big-endian
    // Reproduce MB-System's writer: N for ranges only while byte 117 says 1 (§4.2). Only
    // meaningful for a v1.10 ping with intensity_included; intensities are then not written.
    bool mbsystem_short_length = false;
};

// Appends the record for `ping` to `out`. v1.00 writes zeros at 100-255 and never writes
// intensities. Returns false (appending nothing) if the ping cannot be encoded: B outside
// 1..480, or intensity_included with intensities.size() != B.
bool EncodeRecord83P(const Ping83P& ping,
                     const EncodeOptions& options,
                     std::vector<std::uint8_t>& out);
// Same, returning a new vector (empty on failure).
std::vector<std::uint8_t> EncodeRecord83P(const Ping83P& ping, const EncodeOptions& options = {});
// An MB-System comment record with `text` (truncated to 247 characters).
std::vector<std::uint8_t> EncodeComment83P(std::string_view text,
                                           std::uint8_t format_version = kVersion110);

// Field helpers (§1.4), exposed for tests and for the simulator.
// Date "DD-MMM-YYYY" (month case-insensitive), time "HH:MM:SS", fraction ".hh" or ".mmm":
// Unix microseconds, or nullopt when not parsable.
std::optional<std::int64_t> ParseHeaderClock(std::string_view date,
                                             std::string_view time,
                                             std::string_view fraction);
// Latitude / longitude strings parsed by position; NaN when blank, all zero or malformed.
double ParseLatitudeText(std::string_view text14);
double ParseLongitudeText(std::string_view text14);
// Fill the text fields and their decoded values consistently. The header clock is written
// with hundredths and (v1.10 only) milliseconds; the decoded utime keeps the resolution of the
// version (hundredths for v1.00, ms for v1.10), so set format_version first. Times before year 0 or
// after 9999 make the clock "not parsable". NaN latitude/longitude writes blanks.
void SetHeaderTime(Ping83P& ping, std::int64_t utime_unix);
void SetHeaderLatitude(Ping83P& ping, double latitude_deg);
void SetHeaderLongitude(Ping83P& ping, double longitude_deg);

}  // namespace pitmap::protocol::deltat
