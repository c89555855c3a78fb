// SPDX-License-Identifier: MIT
// Co-registration of two surveys of one site on the terrain that did not change: the rigid
// correction that carries survey B's surface onto survey A's, estimated by iteratively
// reweighted Gauss-Newton on point-to-plane distances from B's grid nodes to A's surface,
// coarse to fine. Changed terrain (a slump, a heap, a cut) gives large residuals and is
// down-weighted (Cauchy kernel on residuals whitened by the robust spread, MAD) or rejected
// (beyond outlier_sigmas): it never pulls the correction.
//
// The correction maps a point p of B (its CRS, metres) to A's frame:
//   T(p) = R (p - pivot) + pivot + t,   R = exp([w]x), w = (roll, pitch, yaw) rad about east,
// north, up; pivot the centroid of the overlap (so that t and w are nearly uncorrelated).
// Per point (node q of B carried to q' = T(q)), with A's height H and gradient g at q'.xy:
//   e = q'.z - H(q'.xy) (vertical),  n = (-g_x, -g_y, 1) / |(-g_x, -g_y, 1)|,  d = e n_z,
// and the Jacobian of d with respect to a left increment (dw, dt) is [((q' - pivot) x n)^T,
// n^T]. Walls (where g is large) fix the horizontal translation and the yaw; floors the
// height, roll and pitch.
// Uncertainty: the formal covariance s^2 (J^T W J)^-1 (s the robust spread of d) grown by
// N_inliers / N_eff with N_eff = overlap area / correlation_length^2: neighbouring nodes share
// their errors (the same pings, the same navigation), so they are not independent samples.
// Thread safety: reentrant.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "processor/compare/surface.hpp"

namespace pitmap::proc::compare {

struct RigidCorrection {
    Eigen::Vector3d pivot = Eigen::Vector3d::Zero();         // m, A's CRS
    Eigen::Vector3d rotation_rad = Eigen::Vector3d::Zero();  // roll, pitch, yaw (rotation vector)
    Eigen::Vector3d translation_m = Eigen::Vector3d::Zero();
    Eigen::Matrix3d R() const;
    Eigen::Vector3d Apply(const Eigen::Vector3d& p) const;
    // The point of B that T carries to (x, y) on the surface B (height from `b`): solved by
    // fixed-point iteration; NaN z when B has no height there.
    Eigen::Vector3d CarryOnto(const SurfaceGrid& b, double x, double y) const;
};

struct RegistrationConfig {
    // Coarse to fine: each level smooths both surfaces by a square mean of this half-width (m)
    // before it iterates; the last level should be 0 (the surfaces as they are).
    std::vector<double> smoothing_m = {3.0, 1.0, 0.3, 0.0};
    int iterations_per_level = 10;
    std::size_t max_points = 80000;     // nodes of B used (a regular subsample)
    double cauchy_width = 2.3849;       // Cauchy kernel width, in robust spreads (95 % eff.)
    double outlier_sigmas = 4.0;        // |d| / s beyond this: not stable terrain, weight 0
    double max_slope_deg = 80.0;        // nodes steeper than this are not used (2.5D walls)
    double min_sigma_m = 0.005;         // floor of the robust spread
    double correlation_length_m = 5.0;  // error correlation length (uncertainty, above)
    bool estimate_roll_pitch = true;    // 6-DoF; false: yaw and translation only
    std::size_t min_points = 500;       // fewer overlapping stable nodes: failure
    // Nodes of either surface with fewer soundings than this (dem.tif's density) are not used:
    // such a node is one or two soundings, not the surface (decision 029). Applied when at
    // least half of the overlap has them, else every node is used (the result says which).
    double min_soundings = 5.0;
    double converged_step_m = 1e-4;  // stop a level when a step moves no node farther

    std::vector<std::string> Validate() const;
};

enum class RegistrationTermination { kConverged = 0, kMaxIterations, kTooFewPoints, kSingular };
const char* ToString(RegistrationTermination t);

struct RegistrationResult {
    RegistrationTermination termination = RegistrationTermination::kTooFewPoints;
    std::string message;
    RigidCorrection correction;
    // 1-sigma of roll, pitch, yaw (rad) and of the translation (m), after the correlation
    // growth; covariance in that order.
    Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> sigma = Eigen::Matrix<double, 6, 1>::Zero();
    std::size_t points_overlap = 0;    // nodes of B (subsampled) with a height of A under them
    std::size_t points_stable = 0;     // of them, inliers at the end (stable terrain)
    double overlap_area_m2 = 0;        // overlap of the two surfaces (all nodes)
    double robust_sigma_m = 0;         // s at the end (point-to-plane)
    double rms_vertical_before_m = 0;  // vertical residual RMS on the final stable nodes,
    double rms_vertical_after_m = 0;   // without and with the correction
    double mean_vertical_after_m = 0;
    // On walls a 2.5D surface's vertical residual is its error along the normal over the
    // slope's cosine (x 2 at 60 deg): the residual along the normal on all the stable nodes,
    // and the vertical one on the floors (slope < 45 deg) only (decision 023, section 6).
    double rms_normal_after_m = 0;
    double rms_vertical_floor_after_m = 0;
    std::size_t points_stable_floor = 0;
    // The soundings a node needed in both surfaces to be used (config.min_soundings, or 0 when
    // too few had them or the density is not known), the overlapping nodes left out by it, and
    // the residuals over every overlapping node, those included (stable: as above).
    double min_soundings_applied = 0;
    std::size_t points_sparse = 0;
    double rms_vertical_all_nodes_after_m = 0;
    double rms_normal_all_nodes_after_m = 0;
    std::size_t points_stable_all_nodes = 0;
    int iterations = 0;
    bool ok() const {
        return termination == RegistrationTermination::kConverged ||
               termination == RegistrationTermination::kMaxIterations;
    }
};

// B onto A. Both grids in one CRS and vertical datum (the caller checks).
RegistrationResult RegisterSurfaces(const SurfaceGrid& a,
                                    const SurfaceGrid& b,
                                    const RegistrationConfig& config);

}  // namespace pitmap::proc::compare
