// SPDX-License-Identifier: MIT
#include "common/protocol/novatel/crc32.hpp"

#include <zlib.h>

#include <algorithm>
#include <limits>

namespace pitmap::protocol::novatel {

std::uint32_t Crc32(ByteSpan data, std::uint32_t crc) {
    // zlib computes the same reflected polynomial with init and final XOR 0xFFFFFFFF:
    // zlib(c, d) = F(c ^ ~0, d) ^ ~0, so F(crc, d) = zlib(crc ^ ~0, d) ^ ~0.
    uLong z = static_cast<uLong>(crc ^ 0xFFFFFFFFu);
    const std::uint8_t* p = data.data();
    std::size_t left = data.size();
    while (left > 0) {
        const auto chunk =
            static_cast<uInt>(std::min<std::size_t>(left, std::numeric_limits<uInt>::max()));
        z = crc32(z, p, chunk);
        p += chunk;
        left -= chunk;
    }
    return static_cast<std::uint32_t>(z) ^ 0xFFFFFFFFu;
}

}  // namespace pitmap::protocol::novatel
