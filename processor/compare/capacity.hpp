// SPDX-License-Identifier: MIT
// The capacity curve of a pit from one surface: for each water level, the area of the water
// surface and the volume of water over the surveyed nodes,
//   area(L) = cell^2 #{nodes: z < L},   volume(L) = cell^2 sum over nodes of max(0, L - z).
// Only the surveyed area counts (empty nodes are not filled in): surveyed_area_m2 says how
// much of the pit that is.
#pragma once

#include <vector>

#include "processor/compare/surface.hpp"

namespace pitmap::proc::compare {

struct CapacityRow {
    double level_m = 0;  // water level, the surface's vertical datum
    double area_m2 = 0;
    double volume_m3 = 0;
};

struct CapacityResult {
    double water_level_m = 0;  // the survey's own water level
    double min_height_m = 0;   // the deepest node
    double surveyed_area_m2 = 0;
    double area_at_water_level_m2 = 0;
    double volume_at_water_level_m3 = 0;
    std::vector<CapacityRow> rows;  // every step_m from the deepest node up, and water_level_m
};

// Precondition: step_m > 0. An empty surface gives no rows.
CapacityResult ComputeCapacity(const SurfaceGrid& s, double water_level_m, double step_m);

}  // namespace pitmap::proc::compare
