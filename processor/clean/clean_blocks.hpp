// SPDX-License-Identifier: MIT
// The cleaning (processor/clean/clean.hpp) on a view read in blocks (issue 38,
// docs/decisions/037-clean-stage-by-view-blocks.md): the view (38 bytes a sounding) need not be
// held. Steps 1-4 read it in order a block at a time, as often as they need (the voxels; the
// plane fits, `fit_soundings` soundings' positions at a time; the rays; the marches behind the
// clusters), holding per sounding only its voxel, its ray's first crossing, the clusters' marks
// and its status; the voxels are held whole (the evidence is the survey's space: every pass over
// a place). Steps 5-8 hold the soundings' ranges on their (ping, beam) grid without their
// positions (14 bytes a sounding). The verdicts are those of the whole view whatever the blocks:
// every array is indexed by the sounding's place in the view, and every sum is over the same
// soundings in the same order.
// Failure model: Clean's, and a block that cannot be read (the sweep's error, returned).
#pragma once

#include <cstddef>
#include <functional>
#include <vector>

#include "common/progress.hpp"
#include "common/result.hpp"
#include "processor/clean/clean.hpp"
#include "processor/georef/georef.hpp"

namespace pitmap::proc::clean {

// A view read in blocks: `sweep(take)` calls take(block) on consecutive blocks of the view's
// points in their order (any sizes, the first sounding first) until all `size` are given, and
// returns the reading's error, if any. `pings`: the view's pings (GeorefPoints::ping indexes
// them).
using TakeBlock = std::function<void(const georef::GeorefPoints&)>;
struct ViewBlocks {
    std::size_t size = 0;
    const std::vector<georef::GeorefPing>* pings = nullptr;
    std::function<Status(const TakeBlock&)> sweep;
};

// The soundings whose positions a plane-fit batch holds at a time (24 bytes each).
inline constexpr std::size_t kFitSoundings = std::size_t{1} << 23;

// Clean on a view read in blocks (above): Clean's verdicts and counts, whatever the blocks (Clean
// is this on one block). The view is read 4 + (the plane-fit batches) times (3 + them without
// clusters); an error when a block could not be read or the blocks do not add up to `size`
// soundings.
Expected<CleanResult> CleanBlocks(const ViewBlocks& view,
                                  const CleanConfig& config,
                                  const ProgressCallback& progress = {},
                                  std::size_t fit_soundings = kFitSoundings);

}  // namespace pitmap::proc::clean
