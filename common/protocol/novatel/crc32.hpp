// SPDX-License-Identifier: MIT
// NovAtel OEM CRC-32 (shared/specs/novatel_oem.md §4; OEM7 manual "32-Bit CRC"):
// reflected CRC-32, polynomial 0xEDB88320, initial value 0, no final XOR.
// Binary frames: over sync..last body byte, stored little-endian after the body.
// ASCII logs: over the characters strictly between '#'/'%' and '*', as 8 hex digits.
#pragma once

#include <cstdint>

#include "common/byte_io.hpp"

namespace pitmap::protocol::novatel {

// CRC of `data`, continuing from `crc` (0 to start).
std::uint32_t Crc32(ByteSpan data, std::uint32_t crc = 0);

}  // namespace pitmap::protocol::novatel
