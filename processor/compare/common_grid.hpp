// SPDX-License-Identifier: MIT
// Two surveys' surfaces on one grid before their DEM of difference (issue 37, decision 030).
// `pitmap run` picks each survey's CUBE resolution from its own median depth, so two surveys
// of one pit can come out at different resolutions (bejanca: A 0.1 m, B 0.2 m). CUBE's node is
// not a point sample of the terrain: it estimates the height from the soundings within a
// capture distance of 0.71-1.5 resolutions, their variance grown with (distance /
// resolution)^2, carried along a predicted surface of 4-resolution cells. A 0.2 m surface is
// smoother at a bench's crest or a riser's foot than a 0.1 m one by more than any filter of the
// finer grid reproduces, and the difference reads as change along every edge. So the coarser
// survey is gridded again, from its own accepted soundings through the same CUBE, at the finer
// resolution on the same global lattice (node i at i x resolution); the DoD then compares two
// surfaces made the same way, node for node.
#pragma once

#include <functional>
#include <string>

#include "common/result.hpp"
#include "processor/compare/surface.hpp"

namespace pitmap::proc::compare {

enum class Regridded { kNone, kA, kB };
const char* ToString(Regridded r);  // "none", "a", "b"

struct CommonGridPlan {
    Regridded regrid = Regridded::kNone;  // the survey gridded again
    double resolution_m = 0;              // the common resolution: the finer of the two
};

// Which survey is gridded again, and at what resolution. Resolutions within 1e-9 m of each
// other are one. Precondition: both > 0.
CommonGridPlan PlanCommonGrid(double resolution_a_m, double resolution_b_m);

// A survey's surface gridded again at `resolution_m` by the caller (CUBE on its accepted
// soundings), or an error naming why not.
using RegridSurvey = std::function<Expected<SurfaceGrid>(double resolution_m)>;

struct CommonSurfaces {
    SurfaceGrid a, b;
    CommonGridPlan plan;
};

// The two surfaces at one resolution: as they are when theirs agree, else the coarser one
// replaced by regrid_a or regrid_b (the one the plan names) at the finer resolution. An error
// when the regrid fails, holds no height or comes back at another resolution.
Expected<CommonSurfaces> OnCommonGrid(SurfaceGrid a,
                                      SurfaceGrid b,
                                      const RegridSurvey& regrid_a,
                                      const RegridSurvey& regrid_b);

}  // namespace pitmap::proc::compare
