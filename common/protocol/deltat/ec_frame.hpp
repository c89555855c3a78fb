// SPDX-License-Identifier: MIT
// Imagenex Delta T External Control ("EC") frame: the 256-byte UDP frame a host sends back
// to the topside software to set the sonar (range, sector, beams, gain, sound velocity, ...).
//
// Reference: shared/specs/imagenex_deltat.md §3.2 (byte table; fields tagged [1] come from a
// single open driver, LSTS DUNE ExternalControl.hpp). Bytes not in the table are written 0
// and ignored by the decoder.
// Failure model: the decoder returns DecodeError (kTruncated / kTrailingBytes for a size other
// than 256, kBadMarker without `EC`, kBadValue for a code outside its table); the encoder
// returns false for a value it cannot represent. Reentrant, no allocation in the decoder.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <variant>
#include <vector>

#include "common/byte_io.hpp"
#include "common/protocol/deltat/messages.hpp"

namespace pitmap::protocol::deltat {

inline constexpr std::size_t kEcFrameBytes = 256;

enum class EcBeamWidth : std::uint8_t { kWide = 0, kNormal = 1, kNarrow = 2, kNarrowMixed = 3 };
enum class EcMode : std::uint8_t {
    kSector = 0,
    kLinear = 1,
    kPerspective = 2,
    kProfile = 3,
    kBeamTest = 4
};
enum class EcOutput : std::uint8_t { k83P = 0, k83B = 1, k83F = 2 };
enum class EcProfileFilter : std::uint8_t { kFirstReturn = 0, kMaxReturn = 1, kBottomFollow = 2 };

// Range code (byte 7) <-> range setting in metres: 2=5 m, 3=10, 4=20, 5=30, 6=40, 7=50,
// 8=60, 9=80, 10=100, 11=150, 12=200, 13=250, 14=300.
std::optional<std::uint16_t> EcRangeMetresFromCode(std::uint8_t code);
std::optional<std::uint8_t> EcRangeCodeFromMetres(std::uint16_t range_m);
// Sector (byte 11): 0=30, 1=60, 2=90, 3=120 degrees.
std::optional<std::uint16_t> EcSectorDegFromCode(std::uint8_t code);
std::optional<std::uint8_t> EcSectorCodeFromDeg(std::uint16_t sector_deg);
// Beams (byte 13): 0=480, 1=240, 2=120.
std::optional<std::uint16_t> EcBeamsFromCode(std::uint8_t code);
std::optional<std::uint8_t> EcBeamsCodeFromCount(std::uint16_t num_beams);

// Every field of §3.2, decoded (tables resolved to physical values).
struct EcFrame {
    bool external_control = true;        // byte 3: 1 external, 0 local
    bool receive_only = false;           // byte 4: 0 transmit+receive, 1 receive only [1]
    std::uint16_t range_m = 50;          // byte 7, via the range code table
    std::uint8_t start_gain_db = 10;     // byte 8
    std::uint8_t display_gain_pct = 50;  // byte 9
    bool gain_equalisation = false;      // byte 10
    std::uint16_t sector_deg = 120;      // byte 11, via the sector table
    EcBeamWidth beam_width = EcBeamWidth::kNormal;  // byte 12
    std::uint16_t num_beams = 480;                  // byte 13, via the beams table
    std::uint8_t averaging = 0;                     // byte 14: 0/1 off, 2-10 shots
    std::uint16_t persistence_s = 0;                // bytes 15-16 BE [1]
    double sound_velocity_mps = 1500.0;             // bytes 17-18: x10, u16 BE
    EcMode mode = EcMode::kProfile;                 // byte 19
    EcOutput output = EcOutput::k83P;               // byte 20 [1]
    bool profile_points = true;                     // byte 21
    std::uint8_t profile_min_range_m = 0;           // byte 22
    std::uint8_t profile_min_level_pct = 10;        // byte 23 (10-90)
    bool transducer_up = false;                     // byte 24: 0 down, 1 up
    std::int16_t profile_tilt_deg = 0;              // byte 25: tilt + 180, so -180..75
    bool roll_compensation = false;                 // byte 26 [1]
    bool record_837 = false;                        // byte 28 [1]
    bool record_83p = false;                        // byte 29 [1]
    std::uint8_t control = 0;                       // byte 31 [1], meaning unknown: kept raw
    std::uint16_t trigger_delay = 0;                // bytes 32-33 BE [1], unit unknown: kept raw
    EcProfileFilter profile_filter = EcProfileFilter::kFirstReturn;  // byte 34 [1]
};

// Decodes exactly 256 bytes. Boolean bytes accept 0/1 only; averaging 0..10; min level
// 0..100; every coded byte must be in its table (kBadValue with the byte's offset).
std::variant<EcFrame, DecodeError> DecodeEcFrame(ByteSpan frame);
// Appends 256 bytes; false (nothing appended) if a value has no code (range, sector, beams),
// the sound velocity does not fit 0..6553.5 m/s, or the tilt is outside -180..75.
bool EncodeEcFrame(const EcFrame& frame, std::vector<std::uint8_t>& out);
std::vector<std::uint8_t> EncodeEcFrame(const EcFrame& frame);  // empty on failure

}  // namespace pitmap::protocol::deltat
