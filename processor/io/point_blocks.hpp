// SPDX-License-Identifier: MIT
// The point files written from a view read a block at a time (decision 033): from the view's
// scratch file (io::SpilledPoints::ReadBlock) or from points held, the same bytes.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "processor/io/products.hpp"

namespace pitmap::proc::io {

// A view's soundings a block at a time: held in memory (`held`, one block), or `size`
// soundings read `block` at a time by `read` (io::SpilledPoints::ReadBlock: soundings
// first .. first + count - 1 into `out`).
struct PointBlocks {
    const georef::GeorefPoints* held = nullptr;
    std::size_t size = 0;
    std::size_t block = std::size_t{1} << 20;
    std::function<Status(std::size_t first, std::size_t count, georef::GeorefPoints& out)> read;
};
// The blocks of points held in memory (`points` must outlive them).
PointBlocks HeldPoints(const georef::GeorefPoints& points);
// Calls visit(points, first) for each block in order (first: the index of points[0] in the
// view); the first error of a read stops it.
Status ForEachBlock(
    const PointBlocks& blocks,
    const std::function<void(const georef::GeorefPoints& points, std::size_t first)>& visit);

// SoundingIntensity of sounding i of `points`, a block of `g`'s view (its ping indices into
// g.pings).
std::uint16_t SoundingIntensity(const georef::GeorefResult& g,
                                const georef::GeorefPoints& points,
                                std::size_t i,
                                const survey::PingSeries& pings);

// WritePly's file with the accepted soundings from `accepted` (read a block at a time;
// `result` gives their pings and the world origin, its points are not read). A read error is
// an error and leaves no file.
Status WritePly(const std::string& path,
                const georef::GeorefResult& result,
                const PointBlocks& accepted,
                const PointExtras* extras = nullptr,
                const std::string& run_id = "",
                const georef::GeorefResult* rejected = nullptr);
// WriteLas's file (the soundings placed by `utm`) with the accepted soundings from `accepted`
// (read a block at a time: once for the bounds, once for the noise classes when rejected
// soundings are written, once for the records; `result` gives their pings, its points are not
// read). A read error is an error and leaves no file.
Status WriteLas(const std::string& path,
                const georef::GeorefResult& result,
                const PointBlocks& accepted,
                const georef::UtmProjection& utm,
                const PointExtras* extras = nullptr,
                const std::string& run_id = "",
                const georef::GeorefResult* rejected = nullptr,
                const ProductMetadata* meta = nullptr);
// LasNoiseClasses with the accepted soundings read a block at a time; a read error is an error.
Expected<std::vector<std::uint8_t>> LasNoiseClassesOf(const PointBlocks& accepted,
                                                      const georef::GeorefPoints& rejected,
                                                      double cell_m = 2.0);

}  // namespace pitmap::proc::io
