// SPDX-License-Identifier: MIT
// A survey against a design surface (issue 37 item 3): the planned cut or fill of a mine plan,
// given as a grid of heights. Per node of the survey's grid: the difference survey - design
// (the design sampled bilinearly at the node; NaN where either has no height), its 95 %
// uncertainty (the survey's node uncertainty; the design is taken as exact) and whether the
// survey is significantly above (+1: material still to cut), below (-1: cut deeper than
// planned, or fill still to place) or on the design (0).
// Volumes between them over the nodes with both: above = sum of the positive differences, below
// = sum of the negative ones, times the cell area. Their 95 % uncertainty takes the survey's node
// errors as fully correlated over the area, U95 = z95 sum(sigma_i) cell over the nodes counted:
// against a design there is no co-registration to remove what a survey's nodes share (its
// navigation's height, its vertical datum, its sound speed), and over a pit those shared errors
// dominate (the independent part would average out). Nodes whose difference is within their
// own U95 add to both bounds through that same sum.
// Thread safety: reentrant.
#pragma once

#include <string>
#include <vector>

#include "processor/compare/change_mesh.hpp"
#include "processor/compare/surface.hpp"

namespace pitmap::proc::compare {

struct DesignConfig {
    double z95 = 1.96;
    std::vector<std::string> Validate() const;
};

struct DesignResult {
    // On the survey's grid: survey - design (m), its U95 (m), significance (-1, 0, +1); NaN where
    // not both.
    std::vector<float> difference_m, u95_m, significance;
    std::size_t compared_nodes = 0;
    double compared_area_m2 = 0;
    double above_m3 = 0, above_area_m2 = 0;  // survey above the design (still to cut)
    double below_m3 = 0, below_area_m2 = 0;  // survey below the design (negative volume)
    double above_u95_m3 = 0, below_u95_m3 = 0;
    double significant_above_area_m2 = 0, significant_below_area_m2 = 0;
    // The same over the significant nodes only (where the survey is beyond its own U95 of the
    // design): a tighter figure that leaves out what lies within the survey's uncertainty.
    double significant_above_m3 = 0, significant_above_u95_m3 = 0;
    double significant_below_m3 = 0, significant_below_u95_m3 = 0;
    double mean_difference_m = 0;
    std::string message;
};

// A design given as a triangle mesh (in the survey's CRS), as heights on the nodes of `like`:
// the highest crossing of the vertical through each node with the mesh's triangles (a 2D index
// of the triangles by their footprint, 1 m cells); NaN where none.
SurfaceGrid RasterizeMesh(const TriangleMesh& mesh, const SurfaceGrid& like);

// `design`: any north-up grid in the survey's CRS and vertical datum (sigma_m unused).
DesignResult CompareWithDesign(const SurfaceGrid& survey,
                               const SurfaceGrid& design,
                               const DesignConfig& config);

}  // namespace pitmap::proc::compare
