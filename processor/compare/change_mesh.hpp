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
//             does not average out over a patch (test_patch_mean; the rest set to 0);
//             then each kept patch grown by hysteresis (grow_lod_fraction, grow_max_m) into the
//             measured vertices joined to it by an edge whose distance has its sign and exceeds
//             half their LoD95, at most 0.5 m from it along the edges, unless the soundings'
//             cores near the vertex contradict it (none significant with its sign, their mean
//             further than half its LoD95 from its distance): a change that tapers (a slump's
//             scar, a lobe's rim) is beyond the LoD95 well inside its outline, and the rim
//             between is the same change at a lower confidence next to a detected one (quarry
//             scar: 22.7 % of its outline below the LoD95, IoU 0.776 -> 0.883; decision 029);
//   regions: each patch kept is a change region on the surface (walls and overhangs included),
//             with its signed volume along its axis u (the area-weighted mean of its vertices'
//             normals): sum(a_i |n_i . u| t_i), a_i a third of vertex i's triangles' area, t_i
//             the distance from the vertex along u to A's surface (the vertex's own distance
//             and a_i where A is not met along u): parallel prisms that tile the volume between
//             the surfaces (u vertical on a floor: the 2.5D volume); and its 95 % uncertainty,
//             as the 2.5D regions' (change.hpp), with a'_i = a_i |n_i . u|:
//               V   = sum(a'_i (t_i - o)), o the two meshes' offset along u on the
//                     unchanged ground around the region: the median distance of the measured
//                     vertices 1-3 m from it with no detectable change whose normals lie within
//                     30 deg of u (at least 50 of them, else o = 0). The two TSDF meshes of one
//                     unchanged floor differ by +-1 cm over 5-10 m (each survey's own
//                     footprints, angles and navigation): on bejanca +6.6 mm around the spill,
//                     +0.6 m^3 over its 92 m^2 (+4 %), where the 1 m correlation of sigma_rand
//                     treats it as noise that averages out;
//               + M, M = sum over the measured vertices with no detectable change within
//                     margin_band_m (0.5 m) of the region of a'_i (d_i - o): the margin a
//                     change that tapers leaves below detection beyond its outline, measured
//                     (bejanca's scar: -0.41 m^3 of true loss outside its region; a rim bound
//                     of one ring of vertices counted 0.21);
//               U95 = z95 sqrt(sigma_rand^2 + sigma_reg^2 + sigma_o^2 + sigma_M^2) + U_rim,
//                     sigma_M^2 = min(L^2, sum a'_i) sum(a'_i (LoD95_i / z95)^2) over the band
//               sigma_rand^2 = min(L^2, sum a'_i) sum(sigma_i^2 a'_i)   (sigma_i = sigma_ab
//                              at the vertex; errors shared over L =
//                              error_correlation_length_m)
//               sigma_reg^2  = (sum a'_i J_i) C (sum a'_i J_i)^T, J_i along u (one correction)
//               sigma_o      = sum(a'_i) 1.2533 s / sqrt(max(1, band area / L^2)), s the band's
//                              distances' 1.4826 MAD (the standard error of their median, the
//                              band's errors shared over L)
//               U_rim        = sum over the measured vertices bordering the region (by an
//                              edge) of min(|d_i|, LoD95_i) a_i (what the outline may leave
//                              below detection along its rim)
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
    // Hysteresis (decision 029): a kept patch grows into the vertices joined to it by an edge
    // whose distance has its sign and exceeds this share of their LoD95 (0: no growth).
    double grow_lod_fraction = 0.5;
    double grow_max_m = 0.5;                  // ... at most this far from it along the mesh's edges
    double error_correlation_length_m = 1.0;  // vertices closer than this share their errors
    // A region's volume against the unchanged ground around it (ComputeChangeMesh): the band of
    // measured vertices between these distances from it, with no detectable change, facing
    // within ground_band_max_angle_deg of its axis; at least ground_band_min_vertices of them.
    double ground_band_inner_m = 1.0, ground_band_outer_m = 3.0;
    double ground_band_max_angle_deg = 30.0;
    std::size_t ground_band_min_vertices = 50;
    // The margin a change leaves below detection beyond its outline: the measured vertices with
    // no detectable change within this of the region, their distance above the ground offset
    // added to its volume (0: none).
    double margin_band_m = 0.5;
    std::vector<std::string> Validate() const;
};

// A change region on the surface: one kept patch of significant vertices of one sign.
struct ChangeRegion3d {
    int id = 0;    // 1.. (ChangeMeshResult::region)
    int sign = 0;  // +1 gain (fill, towards the water), -1 loss (cut)
    std::size_t vertices = 0;
    double area_m2 = 0;          // on the surface (not its horizontal projection)
    double volume_m3 = 0;        // signed: sum(a_i d_i)
    double mean_distance_m = 0;  // along the axis: volume over the area projected across it
    double max_abs_distance_m = 0, mean_lod95_m = 0;
    double mean_slope_deg = 0;  // of the normals from vertical, area-weighted
    double sigma_random_m3 = 0, sigma_registration_m3 = 0, rim_m3 = 0, u95_m3 = 0;
    // The two meshes' offset along the axis on the unchanged ground around the region (median),
    // taken off the volume; the band's vertex count (0: too few, no offset) and the offset's
    // 1-sigma times the region's projected area (in U95 with the random term).
    double ground_offset_m = 0, sigma_ground_offset_m3 = 0;
    // The margin below detection within margin_band_m outside the region: sum a'_i (d_i - o),
    // added to the volume, and its 1-sigma (the random term's form over the band).
    double margin_m3 = 0, sigma_margin_m3 = 0;
    std::size_t ground_band_vertices = 0;
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();   // area-weighted, A's CRS
    Eigen::Vector3d direction = Eigen::Vector3d::Zero();  // its mean normal: the volume's axis
    std::size_t off_axis_vertices = 0;  // A not met along the axis: their own normal's prism
    Eigen::Vector3d min = Eigen::Vector3d::Zero(), max = Eigen::Vector3d::Zero();  // bounds
};

// The soundings' change along the normal at their core points (m3c2.hpp), measured cores
// only: what a vertex's change is checked against (ComputeChangeMesh).
struct SoundingsChange {
    std::vector<Eigen::Vector3d> position;  // A's CRS
    std::vector<float> distance_m;          // B - A along the core's normal
    std::vector<int> significance;          // -1, 0, +1
    double radius_m = 0.5;                  // the cores near a vertex: within this
};

struct ChangeMeshResult {
    std::vector<Eigen::Vector3f> normals;  // B's vertex normals (unit; zero where undefined)
    std::vector<float> distance_m;         // B - A along the normal; NaN: not measured
    std::vector<float> lod95_m;            // NaN where not measured
    std::vector<std::int8_t> significance;
    std::size_t measured = 0, gain = 0, loss = 0;  // gain, loss: after the patch test
    std::size_t patches = 0;                       // kept
    std::size_t patches_dropped = 0;               // too small, or their mean within their LoD
    std::size_t vetoed_by_soundings = 0;           // significant vertices the soundings contradict
    std::size_t grown = 0;                         // vertices the kept patches grew into
    std::vector<int> region;                       // per vertex: its region's id, 0 none
    std::vector<ChangeRegion3d> regions;           // id k at k - 1
    std::size_t regions_unconfirmed = 0;           // dropped by ConfirmRegionsBySoundings
    bool flipped = false;  // the mesh was wound into the ground: normals turned over
    double median_lod95_m = 0;
    std::string message;
};

// The regions confirmed by the soundings' change along the normal (m3c2.hpp): a region is kept
// where, of the measured core points within radius_m of its vertices, at least min_share are
// significant with its sign; the others (and regions with no measured core near them) are
// dropped: their vertices' significance and region set to 0, the regions renumbered from 1,
// gain, loss and patches counted again. The two TSDF meshes of one unchanged face can differ
// (each survey's footprints and viewing angles round a bench's crest its own way) where the
// soundings agree. Returns the number of regions dropped.
std::size_t ConfirmRegionsBySoundings(const TriangleMesh& b,
                                      const std::vector<Eigen::Vector3d>& core_positions,
                                      const std::vector<int>& core_significance,
                                      double radius_m,
                                      double min_share,
                                      ChangeMeshResult& r);

// sigma_ab(p): sqrt(sigma_A^2 + sigma_B^2) at p (empty: 0). B's vertices must be in A's frame.
// soundings (may be null): a significant vertex is set to no detectable change, before the
// patches, where the soundings contradict it: at least one measured core within
// soundings->radius_m, none of them significant with the vertex's sign, and the vertex's
// distance further than its LoD95 from their mean distance (the soundings measured the same
// surface and saw no change there). Each survey's TSDF mesh rounds a face its own way (its
// footprints, its viewing angles): on bejanca a 58 deg riser beside the 0.2 m spill came out
// 6-9 cm further out in B's mesh over 13 m^2 where the soundings' cores measured +0.003 m, none
// significant, and the spill's region climbed the riser (+12.7 %; ChangeMeshResult::
// vetoed_by_soundings).
ChangeMeshResult ComputeChangeMesh(const TriangleMesh& b,
                                   const TriangleMesh& a,
                                   const RigidCorrection& correction,
                                   const Eigen::Matrix<double, 6, 6>& covariance,
                                   const ChangeMeshConfig& config,
                                   const std::function<double(const Eigen::Vector3d&)>& sigma_ab,
                                   const SoundingsChange* soundings = nullptr);

}  // namespace pitmap::proc::compare
