// SPDX-License-Identifier: MIT
// The residuals of the semi-rigid SLAM problem, as free functions with optional Jacobians.
//
// Pose perturbation (used everywhere in this folder): a pose T = (R, t) is perturbed by the
// tangent vector delta = (dphi, dt) (rotation first, world frame) as
//     R <- ExpSO3(dphi) * R,   t <- t + dt.
// Rotations stay on the manifold; no Euler angles enter the optimisation (the reference
// implementation's Euler parametrisation rotated scans at line ends by tens of degrees).
// All Jacobians are with respect to this perturbation at delta = 0.
#pragma once

#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "common/se3.hpp"
#include "processor/registration/robust.hpp"

namespace pitmap::proc::slam {

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;
using Matrix36d = Eigen::Matrix<double, 3, 6>;
using Matrix16d = Eigen::Matrix<double, 1, 6>;

// Inverse right Jacobian of SO(3): LogSO3(ExpSO3(phi) * ExpSO3(d)) ~= phi + JrInv(phi) * d.
Eigen::Matrix3d RightJacobianInverseSO3(const Eigen::Vector3d& phi);
// Inverse left Jacobian: LogSO3(ExpSO3(d) * ExpSO3(phi)) ~= phi + JlInv(phi) * d.
Eigen::Matrix3d LeftJacobianInverseSO3(const Eigen::Vector3d& phi);

// Applies the perturbation delta = (dphi, dt) to T (see the file comment).
Pose ApplyIncrement(const Pose& T, const Vector6d& delta);

// p_world = R * x + t; J = dp/d(dphi, dt) = [-Hat(R x), I].
Eigen::Vector3d TransformPoint(const Pose& T_world_vehicle,
                               const Eigen::Vector3d& x_vehicle,
                               Matrix36d* J = nullptr);

// Point-pair residual of the n-scan ICP error (seed paper eq. 2):
//     r = T_a x_a - T_b x_b   (metres, world frame).
Eigen::Vector3d PointPairResidual(const Pose& T_a,
                                  const Eigen::Vector3d& x_a,
                                  const Pose& T_b,
                                  const Eigen::Vector3d& x_b,
                                  Matrix36d* J_a = nullptr,
                                  Matrix36d* J_b = nullptr);

// Point-to-plane residual r = n^T (T_a x_a - T_b x_b), n the unit normal at the target b,
// held fixed during one linearisation.
double PointToPlaneResidual(const Pose& T_a,
                            const Eigen::Vector3d& x_a,
                            const Pose& T_b,
                            const Eigen::Vector3d& x_b,
                            const Eigen::Vector3d& normal_world,
                            Matrix16d* J_a = nullptr,
                            Matrix16d* J_b = nullptr);

// Relative motion between two slices i -> j as the INS measured it:
//     Q = R_j R_i^T (world frame rotation), d = R_i^T (t_j - t_i) (in the frame of slice i).
struct RelativeMotion {
    Eigen::Matrix3d R_world = Eigen::Matrix3d::Identity();
    Eigen::Vector3d d_i_m = Eigen::Vector3d::Zero();
};
RelativeMotion MeasureRelativeMotion(const Pose& T_i, const Pose& T_j);

// Residual of the relative-motion term (rotation rad, then translation m):
//     r = [ LogSO3(R_j R_i^T Q^T) ; R_i^T (t_j - t_i) - d ].
// Zero when the two poses move as measured.
Vector6d RelativeMotionResidual(const Pose& T_i,
                                const Pose& T_j,
                                const RelativeMotion& measured,
                                Matrix6d* J_i = nullptr,
                                Matrix6d* J_j = nullptr);

// Absolute pose term: r = [ LogSO3(R R_prior^T) ; t - t_prior ].
Vector6d AbsolutePoseResidual(const Pose& T, const Pose& T_prior, Matrix6d* J = nullptr);

// The white noise of each INS position output, 1-sigma east, north, up (m), from the track's
// second differences: for consecutive outputs x0, x1, x2 (steps dt0, dt1 below max_step_s,
// within a factor 1.5 of each other) r = (x2 - x1) / dt1 - (x1 - x0) / dt0 is, per axis, the
// noise's w . (e0, e1, e2) with w = (1/dt0, -(1/dt0 + 1/dt1), 1/dt1), plus the vehicle's
// acceleration times dt (sub-mm at 10 Hz for a surface vehicle in waves); sigma^2 =
// median((r / |w|)^2) / 0.4549 (the median of a chi-square with 1 degree of freedom),
// robust to the GNSS recoveries' jumps. The INS's reported sigma omits it (a filter's steady
// error is what it reports); SLAM's nodes are a second apart, so it stays in every ping.
// Zero with fewer than min_triples usable triples.
Eigen::Vector3d PositionWhiteNoise(const std::vector<double>& t_s,
                                   const std::vector<Pose>& T,
                                   double max_step_s = 0.5,
                                   std::size_t min_triples = 100);

// The robust kernels live in the registration core (shared with calibration).
using reg::RobustCost;
using reg::RobustKernel;
using reg::RobustWeight;

}  // namespace pitmap::proc::slam
