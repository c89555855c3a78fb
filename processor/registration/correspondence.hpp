// SPDX-License-Identifier: MIT
// Correspondences between soundings of two passes (or sections) and their information
// matrices. A correspondence pairs a query point with its closest point of another pass; the
// normals come from the local covariance of each side's own neighbourhood (normals.hpp).
//   point-to-point: r = p_a - p_b, the paper's n-scan ICP error (seed paper eq. 2);
//   point-to-plane: r = n^T (p_a - p_b), n the normal of one side;
//   GICP:           r^T (C_a + C_b)^-1 r with plane-like covariances
//                   C = tangent^2 I + (sigma^2 - tangent^2) n n^T.
#pragma once

#include <Eigen/Core>
#include <Eigen/LU>
#include <cstddef>

namespace pitmap::proc::reg {

enum class CorrespondenceType {
    kPointToPoint,  // |p_a - p_b|^2 / point_sigma^2 (the paper)
    kPointToPlane,  // (n_b . (p_a - p_b))^2 / point_sigma^2, n_b from the target's neighbours
    kGicp,          // (p_a - p_b)^T (C_a + C_b)^-1 (p_a - p_b), plane-like covariances
};

template <class Scalar>
struct BasicCorrespondence {
    using Vector = Eigen::Matrix<Scalar, 3, 1>;
    std::size_t query = 0;                  // index of the query point
    std::size_t target = 0;                 // index of its closest point in another pass
    Vector query_normal = Vector::Zero();   // zero: not estimated / none
    Vector target_normal = Vector::Zero();  // zero: not estimated / none
};
using Correspondence = BasicCorrespondence<float>;     // SLAM: float world points
using Correspondence3d = BasicCorrespondence<double>;  // calibration: double world points

// Information matrix (C_a + C_b)^-1 of a GICP pair with unit normals n_a, n_b: sigma along
// the normal, `tangent` along the surface (both 1-sigma, metres).
inline Eigen::Matrix3d GicpInformation(const Eigen::Vector3d& n_a,
                                       const Eigen::Vector3d& n_b,
                                       double sigma,
                                       double tangent) {
    const double s2 = sigma * sigma, t2 = tangent * tangent;
    const Eigen::Matrix3d C = 2.0 * t2 * Eigen::Matrix3d::Identity() +
                              (s2 - t2) * (n_a * n_a.transpose() + n_b * n_b.transpose());
    return C.inverse();
}

}  // namespace pitmap::proc::reg
