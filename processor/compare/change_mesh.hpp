// SPDX-License-Identifier: MIT
// The 3D change on the TSDF mesh (issue 37 item 2): per vertex of survey B's mesh (carried into
// A's frame by the registration's correction), the signed distance to survey A's mesh along
// B's local normal, its level of detection at 95 % and its significance, so that walls of
// 60-90 deg and overhangs are measured where a 2.5D difference cannot be.
//   normal:   B's vertex normal (area-weighted normals of its triangles); the mesh's winding is
//             taken as pointing into the water, and turned over as a whole when the area-
//             weighted mean normal points down (a mesh wound the other way);
//   distance: the line p + t n, |t| <= max_distance_m, against A's triangles (Moller-Trumbore,
//             through a voxel index of A's triangles walked cell by cell, Amanatides-Woo): the
//             hit of smallest |t|; distance = -t (B - A along the normal, > 0 towards the
//             water: a deposit or a bulge is a gain). No hit: NaN (A has no surface there);
//   LoD95 = z95 sqrt(sigma_A^2 + sigma_B^2 + sigma_reg^2): sigma_A, sigma_B the caller's
//             (pitmap compare: both CUBE surfaces' 1-sigma at the vertex's position, the errors
//             a mesh vertex shares with its neighbours' soundings), sigma_reg^2 = J C J^T with
//             J = [((p - pivot) x n)^T, n^T] (the correction's covariance along the normal);
//   significance: +1 gain, -1 loss where |distance| > LoD95, else 0; then, as the 2.5D regions
//             (change.hpp), the significant vertices of one sign joined by the mesh's edges
//             into patches, and a patch kept only where its area (a third of its vertices'
//             triangles) is at least min_patch_area_m2 and its mean distance exceeds
//             sqrt(mean LoD95^2) over it: what a vertex's neighbours share (a pass's errors)
//             does not average out over a patch (test_patch_mean; the rest set to 0).
// Thread safety: reentrant. Results do not depend on the thread count (one thread).
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "processor/compare/registration.hpp"

namespace pitmap::proc::compare {

struct TriangleMesh {
    std::vector<Eigen::Vector3d> vertices;  // m, A's CRS
    std::vector<std::array<int, 3>> triangles;
};

struct ChangeMeshConfig {
    double max_distance_m = 2.0;  // search along the normal this far each way
    double cell_m = 0.5;          // voxel of A's triangle index
    double z95 = 1.96;
    double min_patch_area_m2 = 0.5;  // smaller significant patches are noise
    bool test_patch_mean = true;     // a patch's mean against its LoD (above)
    std::vector<std::string> Validate() const;
};

struct ChangeMeshResult {
    std::vector<Eigen::Vector3f> normals;  // B's vertex normals (unit; zero where undefined)
    std::vector<float> distance_m;         // B - A along the normal; NaN: not measured
    std::vector<float> lod95_m;            // NaN where not measured
    std::vector<std::int8_t> significance;
    std::size_t measured = 0, gain = 0, loss = 0;  // gain, loss: after the patch test
    std::size_t patches = 0;                       // kept
    std::size_t patches_dropped = 0;               // too small, or their mean within their LoD
    bool flipped = false;  // the mesh was wound into the ground: normals turned over
    double median_lod95_m = 0;
    std::string message;
};

// sigma_ab(p): sqrt(sigma_A^2 + sigma_B^2) at p (empty: 0). B's vertices must be in A's frame.
ChangeMeshResult ComputeChangeMesh(const TriangleMesh& b,
                                   const TriangleMesh& a,
                                   const RigidCorrection& correction,
                                   const Eigen::Matrix<double, 6, 6>& covariance,
                                   const ChangeMeshConfig& config,
                                   const std::function<double(const Eigen::Vector3d&)>& sigma_ab);

}  // namespace pitmap::proc::compare
