// SPDX-License-Identifier: MIT
// pitmap-eval's score of the mine-planning layers (P/terrain.tif, P/crawler.tif; processor
// hydro/terrain.hpp) against the simulator's terrain: the same layers computed, with the same
// settings, from the true heights at the DEM's nodes (what a perfect survey would give), then
// compared node by node where both have data.
//   terrain_slope_mean_abs_deg     |slope - true slope|, mean
//   terrain_step_mean_abs_m        |step - true step|, mean
//   terrain_class_agreement        share of nodes whose class (reachable and traversable counted
//                                  as one: "can stand") is the true one
//   terrain_blocked_recall         of the nodes the truth says a crawler cannot stand on (too
//                                  steep, a step, too rough), the share the product says so too
//   terrain_blocked_false_share    of the nodes the product says it cannot stand on, the share
//                                  the truth says it can
#pragma once

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "common/geodesy.hpp"
#include "common/result.hpp"

#include "processor/hydro/terrain.hpp"
#include "tools/sim/world.hpp"

namespace pitmap::eval {

struct TerrainScore {
    std::size_t nodes = 0;  // compared
    double slope_mean_abs_deg = 0, step_mean_abs_m = 0;
    double class_agreement = 0, blocked_recall = 0, blocked_false_share = 0;
};

// The product's layers on the DEM's grid (nx * ny, row-major from the south, NaN = no data;
// classes as their codes) and each node's world (ENU) position, x and y.
struct TerrainLayers {
    int nx = 0, ny = 0;
    double resolution_m = 0;
    std::vector<float> slope_deg, step_m, terrain_class;
    std::vector<Eigen::Vector2d> node_world_xy;
};

std::optional<TerrainScore> ScoreTerrain(const TerrainLayers& product,
                                         const sim::PitWorld& world,
                                         const proc::hydro::TerrainConfig& config);

// Reads P/terrain.tif and P/crawler.tif (their settings from P/summary.json stages.grid.terrain)
// and scores them against the truth's terrain around `origin` (the products' world origin).
// No value when the products have no terrain layers; an error for unreadable ones.
Expected<std::optional<TerrainScore>> ScoreTerrainProducts(const std::string& products_dir,
                                                           const sim::PitWorld& world,
                                                           const Geodetic& origin);

}  // namespace pitmap::eval
