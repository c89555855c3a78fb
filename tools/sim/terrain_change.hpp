// SPDX-License-Identifier: MIT
// Repeat surveys with known change (issue 37): what happened to the pit between two epochs,
// as parts with exact volumes, added to the terrain grid of the first epoch.
//
// A change (a slumped wall section, a backfill deposit, a mined cut) is one or more parts;
// each part is a smooth shape of known volume, raising (gain) or lowering (loss) the terrain
// height z = H(x, y) by thickness_m * profile(x, y) (vertical, metres; profile in [0, 1],
// 0 outside the part's outline):
//   kParaboloid  elliptic paraboloid cap, half axes a (along u) and b (along v):
//                profile = 1 - (u/a)^2 - (v/b)^2;   volume = pi a b t / 2
//   kFrustum     flat-topped cone (a dumped heap at its angle of repose), top radius a,
//                base radius b: profile = clamp((b - r) / (b - a), 0, 1);
//                volume = pi t (a^2 + a b + b^2) / 3
//   kBox         flat-bottomed cut with linear sides: profile = p(u) p(v) with p(s) = 1 for
//                |s| <= half length, falling linearly to 0 over ramp_m beyond it;
//                volume = t (2 a + ramp) (2 b + ramp)
// (u, v) are the part's local axes: u along heading_deg (counter-clockwise from world +x),
// v 90 deg to its left. A slump is two parts, the scar on the wall (loss) and the lobe at its
// toe (gain) of the same volume: material moved, none made.
// World frame: the simulator's ENU (tools/sim/world.hpp).
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "tools/sim/scenario.hpp"
#include "tools/sim/world.hpp"

namespace pitmap::sim {

// ChangeShape and ChangePart are declared in scenario.hpp (a scenario holds its changes).

// ChangePart::Outline is circumscribed: every point whose profile is > 0 lies inside it.

// The height change of all parts on a grid's nodes (same layout as TerrainGrid::height_m).
std::vector<float> ChangeGrid(const TerrainGrid& grid, const std::vector<ChangePart>& parts);

// Sum of one part's height change over the grid's nodes times the cell area: the volume
// measured on the grid (the second way, against AnalyticVolume).
double GridVolume(const TerrainGrid& grid, const ChangePart& part);

// Whether no point of b's outline lies within gap_m of a's (sampled every 0.05 m, the gap on
// 16 directions at 4 distances: within a few per cent).
bool PartsApart(const ChangePart& a, const ChangePart& b, double gap_m);

// The changes a repeat survey of `pit` finds (scaled to the pit's size): a slump of the deepest
// wall at direction ~80 deg (the high wall where there is one, else the last riser), a heap of
// backfill and a thinner spill on the floor, a mined cut in the floor. The rest is stable.
// The parts lie at least 1 m apart (a part placed within that of an earlier one is moved to the
// nearest place apart from them and, with `ground` (the pit before the change), on its floor):
// each part's volume is then what a survey can measure of it.
std::vector<ChangePart> DefaultChanges(const PitConfig& pit, const PitWorld* ground = nullptr);

// The scenario of a repeat survey: epoch 1 is `first` itself; epoch k >= 2 keeps the pit
// (terrain_seed = the first epoch's seed) and adds DefaultChanges, and is surveyed again with
// its own everything else: noise seed, start (k - 1) x 91 days later, the laps run clockwise
// and 1.5 m further from the shore, a remounted sonar (boresight), a topside clock of its own
// (offset and drift). An epoch < 1 or > 9 is an error.
Expected<ScenarioConfig> RepeatEpoch(const ScenarioConfig& first, int epoch);

// The terrain of a scenario: the pit of terrain_seed (seed when 0) with the changes applied.
PitWorld MakeWorld(const ScenarioConfig& sc);

// The pit's capacity: for each water level (world z, up; the survey's water surface is 0),
// the area of the water surface (m^2) and the water's volume (m^3) over the terrain grid.
struct CapacityPoint {
    double level_m = 0;
    double area_m2 = 0;
    double volume_m3 = 0;
};
std::vector<CapacityPoint> CapacityCurve(const TerrainGrid& grid,
                                         double min_level_m,
                                         double max_level_m,
                                         double step_m);

}  // namespace pitmap::sim
