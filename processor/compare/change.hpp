// SPDX-License-Identifier: MIT
// The 2.5D change between two co-registered surfaces (issue 37 item 3): the DEM of difference
// on A's grid (B carried by the registration's correction, minus A), a level of detection per
// node, significance, connected change regions with their volume, its 95 % uncertainty and
// outline, and the totals of cut and fill.
//
// Level of detection at 95 % per node (Brasington et al. 2003; Wheaton et al. 2010, with the
// registration's share added):
//   LoD95 = z95 sqrt(sigma_A^2 + sigma_B^2 + sigma_reg^2)
// sigma_A, sigma_B: the CUBE surfaces' 1-sigma (dem.tif's 95 % uncertainty / 1.96);
// sigma_reg^2 = J C J^T, C the correction's covariance and J = [((p - pivot) x m)^T, m^T],
// m = (-g_x, -g_y, 1) (the vertical effect of the correction's error at p; g the slope, so it
// grows on walls). Significance: +1 where the difference exceeds LoD95 (gain), -1 below
// -LoD95 (loss), 0 otherwise (no detectable change).
// Regions: the significant nodes, grown into 8-neighbours of the same sign whose difference
// exceeds grow_fraction LoD95 (hysteresis: a change's thin edges belong to it), labelled by
// 8-connectivity per sign; regions smaller than min_region_area_m2 are dropped (their nodes
// become 0: isolated noise).
// A region is then tested as a whole (test_region_mean): it is kept only where its mean
// difference exceeds the level of detection of a mean over it,
//   |mean dz| > LoD95_region = z95 sqrt(mean(sigma_A^2 + sigma_B^2) + J_mean C J_mean^T).
// The errors a pass shares (navigation height, attitude, sound speed: CUBE's pass-common part,
// most of a node's sigma where several passes cover it) are the same over neighbouring nodes,
// so over a region they do not average out: its mean carries them whole. The per-node test,
// the hysteresis and the minimum area treat the nodes' errors as independent (a blob of
// exceedances would then be very unlikely); under a pass-common error a patch of neighbours
// exceeds the per-node LoD together as easily as one node does, and the hysteresis grows it
// into a region whose mean lies below the LoD. dem.tif does not split a node's sigma into its
// independent and its common part, so the whole of it is taken as common within a region (the
// independent part would average down: a conservative bound, a region must exceed the LoD on
// average).
// Volume of a region: sum of the differences times the cell area. Its 95 % uncertainty:
//   U95 = z95 sqrt(sigma_rand^2 + sigma_reg^2) + U_rim
//   sigma_rand^2 = n_c sum (sigma_A^2 + sigma_B^2) cell^2   (n_c = nodes per correlation
//                  patch, (error_correlation_length / res)^2, at most the region's nodes)
//   sigma_reg^2  = (sum J) C (sum J)^T cell^2               (one correction for every node)
//   U_rim        = sum over the nodes bordering the region of min(|dz|, LoD95) cell^2
//                  (what the outline may have left out below detection)
// Totals add the regions' random terms in quadrature and the registration and rim terms
// linearly.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "processor/compare/registration.hpp"
#include "processor/compare/surface.hpp"

namespace pitmap::proc::compare {

struct ChangeConfig {
    double z95 = 1.96;                        // the level of detection's quantile
    double grow_fraction = 0.5;               // hysteresis: grow into |dz| > this x LoD95
    double min_region_area_m2 = 0.5;          // smaller regions are not reported
    double error_correlation_length_m = 1.0;  // nodes closer than this share their errors
    bool test_region_mean = true;  // keep a region only where its mean exceeds its LoD (above)
    std::vector<std::string> Validate() const;
};

struct ChangeRegion {
    int id = 0;    // 1.. (the region band of dod.tif)
    int sign = 0;  // +1 gain (fill), -1 loss (cut)
    std::size_t nodes = 0;
    double area_m2 = 0;
    double volume_m3 = 0;  // signed
    double u95_m3 = 0;     // 95 % uncertainty of the volume
    double sigma_random_m3 = 0, sigma_registration_m3 = 0, rim_m3 = 0;  // its terms
    double max_abs_difference_m = 0;
    double mean_lod95_m = 0;
    double mean_difference_m = 0;  // signed, over the region's nodes
    double region_lod95_m = 0;     // the level of detection of that mean (above)
    Eigen::Vector2d centroid = Eigen::Vector2d::Zero();  // m, A's CRS
    // Outline: polygons (outer ring first, then its holes), each ring closed (first point
    // repeated), outer rings counter-clockwise, along the nodes' cell edges.
    std::vector<std::vector<std::vector<Eigen::Vector2d>>> polygons;
};

struct ChangeTotals {
    double volume_m3 = 0;  // signed sum
    double u95_m3 = 0;
    double area_m2 = 0;
    int regions = 0;
};

struct ChangeResult {
    // On A's grid (geometry of `a`): B minus A (NaN where either is empty), LoD95, significance
    // (-1, 0, +1; NaN where no difference), region id (0 none; NaN where no difference).
    std::vector<float> difference_m, lod95_m, significance, region;
    std::vector<ChangeRegion> regions;  // largest |volume| first
    ChangeTotals cut, fill;             // cut: loss (negative volume), fill: gain
    std::size_t compared_nodes = 0;     // nodes with both surfaces
    double compared_area_m2 = 0;
    double significant_share = 0;  // of the compared nodes, in a region
    // Regions of at least the minimum area whose mean stayed within their LoD (dropped).
    int regions_below_detection = 0;
    double area_below_detection_m2 = 0;
    double median_lod95_m = 0;
    // The smallest detectable change (median LoD95, m) by the slope of A's surface: floors and
    // benches (< 20 deg), faces (20-45 deg), walls (>= 45 deg); 0 where no node.
    double median_lod95_floor_m = 0, median_lod95_face_m = 0, median_lod95_wall_m = 0;
    // The difference over the nodes outside every region (stable terrain after the correction).
    double stable_mean_m = 0, stable_rms_m = 0;
    std::string message;
};

// Precondition: `correction` maps B into A's frame (RegisterSurfaces), `covariance` its
// covariance (zero = exact).
ChangeResult ComputeChange(const SurfaceGrid& a,
                           const SurfaceGrid& b,
                           const RigidCorrection& correction,
                           const Eigen::Matrix<double, 6, 6>& covariance,
                           const ChangeConfig& config);

}  // namespace pitmap::proc::compare
