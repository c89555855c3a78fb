// SPDX-License-Identifier: MIT
// Keys of horizontal grid cells (and of unordered index pairs) for hash maps: one packing for
// every grid in calibration and SLAM. Cell indices within +-2^30 of the origin are unique,
// i.e. +-1e9 cells (cells of 1 cm still span +-10 000 km).
#pragma once

#include <cmath>
#include <cstdint>
#include <utility>

namespace pitmap::proc::reg {

inline std::uint64_t CellKey(std::int64_t ix, std::int64_t iy) {
    constexpr std::int64_t kBias = std::int64_t{1} << 30;
    return (static_cast<std::uint64_t>(ix + kBias) << 32) |
           (static_cast<std::uint64_t>(iy + kBias) & 0xFFFFFFFFu);
}

// Cell index of a coordinate on a grid of `cell` metres with a cell corner at 0.
inline std::int64_t CellIndex(double x, double cell) {
    return static_cast<std::int64_t>(std::floor(x / cell));
}

inline std::uint64_t CellKeyOf(double x, double y, double cell) {
    return CellKey(CellIndex(x, cell), CellIndex(y, cell));
}

// The same key for (a, b) and (b, a).
inline std::uint64_t UnorderedPairKey(std::uint32_t a, std::uint32_t b) {
    if (b < a) std::swap(a, b);
    return (static_cast<std::uint64_t>(a) << 32) | b;
}

}  // namespace pitmap::proc::reg
