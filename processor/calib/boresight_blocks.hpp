// SPDX-License-Identifier: MIT
// The boresight calibration (boresight.hpp) on a view read a range at a time (decision 033):
// from the view's scratch file, so that the stage does not hold the survey's soundings.
#pragma once

#include <cstddef>
#include <functional>

#include "processor/calib/boresight.hpp"

namespace pitmap::proc::calib {

// A view's soundings read a range at a time: read(first, end, visit) hands soundings
// first .. end - 1 in order as blocks, visit(points, block_first, lo, hi) for points[lo .. hi),
// which are soundings block_first + lo .. block_first + hi - 1. It returns false when the view
// could not be read (the reader keeps why).
using ViewVisit = std::function<void(
    const georef::GeorefPoints& points, std::size_t block_first, std::size_t lo, std::size_t hi)>;
struct ViewReader {
    std::size_t size = 0;  // soundings in the view
    std::function<bool(std::size_t first, std::size_t end, const ViewVisit& visit)> read;
};
// The reader of points held in memory (one block, no copy); `points` must outlive it.
ViewReader HeldView(const georef::GeorefPoints& points);

// CalibrateBoresight with the view's soundings read through `view`: `geo` gives the pings, the
// mount, the refraction and the world origin, its points are not read. Each candidate window,
// the chosen segment and the segments verified on read only the range of the view their pings
// hold. The same soundings in the same order: the same result.
BoresightResult CalibrateBoresight(const georef::GeorefResult& geo,
                                   const ViewReader& view,
                                   const survey::NavSeries& nav,
                                   const survey::SonarMount& mount,
                                   const BoresightConfig& config,
                                   const ProgressCallback& progress = {});

}  // namespace pitmap::proc::calib
