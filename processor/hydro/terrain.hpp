// SPDX-License-Identifier: MIT
// Mine-planning layers of one survey's DEM (issue 37 item 4): where a bottom crawler can stand
// and drive. Per DEM node, from the nodes of a square window around it:
//
//   slope_deg     the tilt of the least-squares plane of the window (window_m a side: the
//                 crawler's footprint), so one noisy node does not make a slope;
//   roughness_m   the RMS of the window's residuals from that plane (n - 3 degrees of freedom);
//   step_m        the largest height difference left in a smaller window (step_window_m a side:
//                 the length of a track's contact) once the plane is taken out: a ledge, the
//                 flank of a boulder, a bench edge; a constant slope is no step.
//
// This is the slope / roughness / step decomposition of traversability maps for ground robots
// (as in the elevation-map traversability filters of legged and tracked robots); the plane
// sums come from summed-area tables, so a window costs the same however large it is.
//
// A node is traversable when its slope and roughness are within the crawler's limits and no step
// higher than it climbs lies within its footprint (window_m a side: its body would be on it);
// the reachable area is
// the 8-connected set of traversable nodes that holds the launch point (or the traversable node
// nearest to it, within launch_snap_m). Nodes without a height, or whose window holds fewer
// than min_fill of its nodes, are "no data": the survey did not see enough to say.
#pragma once

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace pitmap::proc::hydro {

struct TerrainConfig {
    double window_m = 1.0;                 // slope and roughness: the plane's window, m a side
    double step_window_m = 0.4;            // steps: this window, m a side (within window_m)
    double min_fill = 0.5;                 // share of a window's nodes that must have a height
    double crawler_max_slope_deg = 20;     // steeper is not traversable
    double crawler_max_step_m = 0.3;       // a higher step is an obstacle
    double crawler_max_roughness_m = 0.1;  // rougher is not traversable
    // The launch point in the DEM's projected coordinates (easting, northing, m); NaN = none:
    // no reachable area, only what is traversable.
    double launch_easting = std::numeric_limits<double>::quiet_NaN();
    double launch_northing = std::numeric_limits<double>::quiet_NaN();
    double launch_snap_m = 5.0;  // the launch node is the traversable one nearest, this close

    std::vector<std::string> Validate() const;  // "terrain.KEY ..." problems
};

// What a node is for the crawler (the class band's codes; names in TerrainClassName).
enum class TerrainClass : std::uint8_t {
    kNoData = 0,       // no height, or too few heights in its window
    kReachable = 1,    // traversable and connected to the launch point
    kTraversable = 2,  // within the limits, not connected to the launch point (or none given)
    kTooSteep = 3,
    kStep = 4,  // a step higher than the crawler climbs
    kTooRough = 5,
};
inline constexpr int kTerrainClassCount = 6;
const char* TerrainClassName(TerrainClass c);

// The DEM: heights (m, positive up) on a regular grid, row-major from the south (j * nx + i),
// NaN where empty; x0, y0 the south-west node's centre.
struct TerrainGrid {
    double x0 = 0, y0 = 0, resolution_m = 0;
    int nx = 0, ny = 0;
    const std::vector<float>* height = nullptr;
};

struct TerrainResult {
    std::vector<float> slope_deg, roughness_m, step_m;  // NaN where no data
    std::vector<float> terrain_class;                   // TerrainClass codes as floats
    int window_nodes = 0, step_window_nodes = 0;        // the windows' sides, nodes
    std::int64_t nodes_with_data = 0;
    std::int64_t nodes_by_class[kTerrainClassCount] = {};
    double node_area_m2 = 0;
    bool launch_given = false;
    bool launch_found = false;         // a traversable node within launch_snap_m
    int launch_i = -1, launch_j = -1;  // the launch node
    double launch_snap_distance_m = std::numeric_limits<double>::quiet_NaN();
    std::string message;  // one line for the log
};

TerrainResult ComputeTerrain(const TerrainGrid& dem, const TerrainConfig& config);

}  // namespace pitmap::proc::hydro
