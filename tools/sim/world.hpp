// SPDX-License-Identifier: MIT
// The synthetic open pit: an exact terrain surface z = H(x, y) in the world frame (ENU, origin
// at the pit centre on the water surface, z up), queryable for height, normal, signed distance
// and ray casts. Benches, backfill, a sump and rubble always; optionally a high wall, a haul
// road ramp and boulders (PitConfig). The surface is the bilinear interpolation of a regular grid
// built deterministically from the PitConfig and a seed; that same grid is the ground truth that
// every product is scored against.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <vector>

#include "tools/sim/scenario.hpp"

namespace pitmap::sim {

struct TerrainGrid {
    double x0_m = 0;              // world x of column 0
    double y0_m = 0;              // world y of row 0
    double resolution_m = 0;      // cell size
    int nx = 0;                   // columns (x)
    int ny = 0;                   // rows (y)
    std::vector<float> height_m;  // row-major: height_m[iy * nx + ix], metres (z up)
};

// The haul road of PitConfig::ramp_*: a straight strip whose centre line runs from `top` on
// the water line to `bottom` on the middle of the bench tread, its surface at depth
// u * tan(grade) at u metres from `top` along the line.
struct RampGeometry {
    Eigen::Vector2d top = Eigen::Vector2d::Zero();     // world x, y on the water line
    Eigen::Vector2d bottom = Eigen::Vector2d::Zero();  // world x, y on the bench tread
    double width_m = 0;
    double grade_deg = 0;
    double bottom_depth_m = 0;  // depth of the bench it reaches
    double length_m() const { return (bottom - top).norm(); }
};
// The ramp of a PitConfig, or nullopt when ramp_width_m is 0.
std::optional<RampGeometry> PlanRamp(const PitConfig& pit);

// One boulder laid into the terrain grid.
struct Boulder {
    Eigen::Vector2d centre = Eigen::Vector2d::Zero();  // world x, y
    double diameter_m = 0;                             // long axis of the plan outline
    double height_m = 0;  // top above the surrounding ground (before the boulder)
};

// Thread safety: all const methods may be called concurrently.
class PitWorld {
public:
    PitWorld(const PitConfig& config, std::uint64_t seed);
    // Builds a world over a grid that was written before (truth files).
    explicit PitWorld(TerrainGrid grid);

    const TerrainGrid& grid() const { return grid_; }
    // The boulders laid into the grid (PitConfig::num_boulders; fewer if the pit has too
    // little gentle ground for them). Empty for a world read from a grid.
    const std::vector<Boulder>& boulders() const { return boulders_; }
    // Terrain height at (x, y), metres; outside the grid: the height at the nearest edge.
    double Height(double x, double y) const;
    // Gradient dH/dx, dH/dy of the bilinear surface.
    Eigen::Vector2d Gradient(double x, double y) const;
    // Unit surface normal pointing up (into the water).
    Eigen::Vector3d Normal(double x, double y) const;
    // Signed distance from p to the terrain surface: > 0 above (in the water), < 0 below.
    // Exact for a locally planar surface; refined by re-projection near edges.
    double SignedDistance(const Eigen::Vector3d& p) const;
    // First intersection of the ray origin + t * dir (dir unit) with the terrain, t in
    // (0, max_range_m]; nullopt if none (or if the origin is below the terrain).
    std::optional<double> RayCast(const Eigen::Vector3d& origin,
                                  const Eigen::Vector3d& dir,
                                  double max_range_m) const;
    // Water depth at (x, y): max(0, -Height).
    double Depth(double x, double y) const { return std::max(0.0, -Height(x, y)); }
    // Largest |gradient| over the grid (the Lipschitz bound the ray marcher relies on).
    double max_slope() const { return max_slope_; }
    // Adds delta_m (one value per grid node, same layout) to the heights: a repeat survey's
    // changes (tools/sim/terrain_change.hpp). Precondition: delta_m.size() == nodes.
    void AddHeights(const std::vector<float>& delta_m);

private:
    double At(int ix, int iy) const;
    void ComputeMaxSlope();

    void PlaceBoulders(const PitConfig& pit, std::uint64_t seed);

    TerrainGrid grid_;
    std::vector<Boulder> boulders_;
    double max_slope_ = 1.0;
};

// Distance from (x, y) to the water line of the superellipse pit, measured along the ray from
// the pit centre; > 0 inside the pit, < 0 on land. Used to lay out benches and laps.
double DistanceFromShore(const PitConfig& pit, double x, double y);

// The point at distance d_m from the shore on the ray from the pit centre at direction_deg
// (counter-clockwise from +x).
Eigen::Vector2d PointFromShore(const PitConfig& pit, double direction_deg, double d_m);

// The deepest face of the pit at direction_deg, as distances from the shore along the ray:
// the high wall inside its sector, else the benches' last riser (its top and its foot on the
// floor). Without the noise terms (backfill, rubble): the nominal profile.
struct FaceSpan {
    double top_m = 0;   // where the face starts (the water line for the high wall)
    double foot_m = 0;  // where it meets the floor
};
FaceSpan DeepestFace(const PitConfig& pit, double direction_deg);

}  // namespace pitmap::sim
