// SPDX-License-Identifier: MIT
// Surface extraction from the fused TSDF (seed paper section 4.3, mission step 6): the zero
// level set by OpenVDB volume-to-mesh on the weight-filtered field, vertex colours by depth, and
// a display copy with small holes filled. The raw mesh is never altered by the hole filling.
// World frame: local ENU (z up), metres.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "processor/fusion/tsdf.hpp"

namespace pitmap::proc::mesh {

struct ColouredMesh {
    std::vector<Eigen::Vector3f> vertices;             // world, metres
    std::vector<Eigen::Vector3i> triangles;            // CCW seen from the water side
    std::vector<std::array<std::uint8_t, 3>> colours;  // RGB per vertex (empty = none)

    bool empty() const { return triangles.empty(); }
};

struct MeshConfig {
    double iso_m = 0.0;       // level of the surface in the signed distance field
    int max_hole_edges = 40;  // display mesh: holes bounded by <= this many edges filled
    // Depth colour ramp over z in [colour_min_z_m, colour_max_z_m]; both 0 = the mesh's range.
    double colour_min_z_m = 0.0;
    double colour_max_z_m = 0.0;

    std::vector<std::string> Validate() const;
};

struct HoleFillResult {
    std::int64_t holes_found = 0;      // closed boundary loops (incl. the outer border)
    std::int64_t holes_filled = 0;     // loops of <= max_hole_edges edges
    std::int64_t holes_too_large = 0;  // loops left open
    std::int64_t loops_ambiguous = 0;  // boundary pieces through non-manifold vertices, left open
    std::int64_t triangles_added = 0;
    std::int64_t vertices_added = 0;
};

struct MeshResult {
    ColouredMesh mesh;                     // raw iso-surface (observed cells only)
    ColouredMesh mesh_filled;              // display mesh: raw + small holes filled
    std::int64_t polygons_raw = 0;         // from volume-to-mesh
    std::int64_t polygons_unobserved = 0;  // dropped at cells with an unobserved corner
    HoleFillResult holes;
    double area_m2 = 0;  // raw mesh area
    double min_z_m = 0;  // raw mesh z range
    double max_z_m = 0;
    std::string message;
};

// THREADING: volume-to-mesh runs on OpenVDB's TBB workers; the rest is single-threaded.
// Precondition: config.Validate() is empty. An empty volume gives empty meshes (not an error).
MeshResult RunMesh(const fusion::TsdfVolume& volume, const MeshConfig& config);

// Pure helpers (exposed for tests).
// Fills boundary loops of at most max_edges edges with a fan around the loop's centroid.
HoleFillResult FillSmallHoles(std::vector<Eigen::Vector3f>& vertices,
                              std::vector<Eigen::Vector3i>& triangles,
                              int max_edges);
// Colour ramp (deep = dark blue ... shallow = red/yellow) by z in [min_z, max_z].
std::array<std::uint8_t, 3> DepthColour(double z_m, double min_z_m, double max_z_m);
double MeshArea(const std::vector<Eigen::Vector3f>& vertices,
                const std::vector<Eigen::Vector3i>& triangles);

}  // namespace pitmap::proc::mesh
