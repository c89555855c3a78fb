// SPDX-License-Identifier: MIT
// 3D change along the local normal between two point clouds (issue 37 item 2), after the
// M3C2 algorithm (Lague, Brodu & Leroux 2013, "Accurate 3D comparison of complex topography
// with terrestrial laser scanner", ISPRS J. 82): so that walls of 60-90 deg and overhangs are
// measured along their normal, where a 2.5D difference sees a horizontal shift as a change of
// height.
//   core points: A's soundings thinned to one per core_spacing_m voxel (the first met);
//   normal: the plane fit (registration core, normals.hpp) of both surveys' soundings within
//           normal_radius_m (A's alone may be one swath's edge), oriented up, or towards
//           `inside` (the pit's interior, where the water is) when it is within 25 deg of
//           horizontal; not measured (not_planar) where either survey's own soundings there
//           are not a plane (max_planarity_ratio: a ridge's crest, a boulder, a corner);
//   distance: along the normal, mean of B's minus mean of A's soundings in the cylinder of
//           projection_radius_m about it (half-length max_depth_m), each over the surface
//           nearest to the core (the cylinder's soundings split at gaps of surface_gap_m along
//           its axis: A's group holding the core, B's nearest to A's; not a ridge's far face);
//   LoD95 = z95 sqrt(s_A^2 / n_A + s_B^2 / n_B + sigma_common^2 + sigma_reg^2) (M3C2's
//           spatially variable level of detection from the roughness s and the counts n; the
//           soundings of a cylinder share most of their errors (navigation, attitude, sound
//           speed: the survey's TPU), which s / sqrt(n) does not see, so sigma_common (the
//           caller's, e.g. both CUBE surfaces' 1-sigma there) is added whole; and the
//           registration's covariance C along the normal: sigma_reg^2 = J C J^T, J = [((c -
//           pivot) x n)^T, n^T]); significance -1 / 0 / +1 as the 2.5D change. Cores with fewer
//           than min_points soundings of either survey in their cylinder have no distance (NaN).
// Coordinates: any metric CRS (pitmap: UTM); B's soundings must be carried by the correction
// already. Thread safety: reentrant (one thread).
#pragma once

#include <Eigen/Core>
#include <functional>
#include <string>
#include <vector>

#include "processor/compare/registration.hpp"

namespace pitmap::proc::compare {

struct M3c2Config {
    double core_spacing_m = 0.5;
    double normal_radius_m = 1.0;
    double projection_radius_m = 0.5;
    double max_depth_m = 2.0;
    // Soundings of one survey in a cylinder more than this apart along its axis belong to two
    // surfaces (the near face and the far face of a ridge); the one nearest to the core counts.
    double surface_gap_m = 0.3;
    // The normal is defined where both surveys' soundings within normal_radius_m form a plane:
    // the smallest eigenvalue of their covariance below this times the middle one (a plane of
    // 1 m radius with a few centimetres of roughness: about 0.01; a ridge's crest: 0.2-0.3).
    double max_planarity_ratio = 0.1;
    int min_points = 5;
    double z95 = 1.96;
    // A significant core keeps its significance only with at least this many significant cores
    // of its sign (itself included) within cluster_radius_m: an isolated one is noise (as the
    // 2.5D regions under their minimum area).
    int min_cluster_cores = 4;
    double cluster_radius_m = 1.0;
    std::vector<std::string> Validate() const;
};

struct M3c2Core {
    Eigen::Vector3d position = Eigen::Vector3d::Zero();
    Eigen::Vector3d normal = Eigen::Vector3d::Zero();
    float distance_m = 0;  // NaN: too few soundings
    float lod95_m = 0;
    int significance = 0;
    int n_a = 0, n_b = 0;
    float slope_deg = 0;  // of the normal from vertical
};

struct M3c2Result {
    std::vector<M3c2Core> cores;
    std::size_t measured = 0;     // cores with a distance
    std::size_t significant = 0;  // of them, significant (in a cluster)
    std::size_t isolated = 0;     // significant on their own, not counted (set to 0)
    std::size_t not_planar = 0;   // cores without a plane at the normal's scale (not measured)
    std::string message;
};

// `inside`: a point of the pit's interior (the normals of walls point towards it).
M3c2Result RunM3c2(const std::vector<Eigen::Vector3d>& a,
                   const std::vector<Eigen::Vector3d>& b,
                   const Eigen::Vector3d& inside,
                   const RigidCorrection& correction,
                   const Eigen::Matrix<double, 6, 6>& covariance,
                   const M3c2Config& config,
                   const std::function<double(const Eigen::Vector3d&)>& sigma_common = {});

}  // namespace pitmap::proc::compare
