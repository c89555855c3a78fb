// SPDX-License-Identifier: MIT
// Surface normals from the covariance of a neighbourhood (principal component analysis): the
// eigenvector of the smallest eigenvalue. Calibration gathers neighbours by radius within one
// pass, SLAM by count within one section; both fit them here.
#pragma once

#include <Eigen/Core>

namespace pitmap::proc::reg {

// First and second moments of a point set, accumulated about the first point added (so that
// world coordinates of hundreds of metres lose no digits against centimetre neighbourhoods).
class MomentAccumulator {
public:
    // Inline: calibration and SLAM add tens of neighbours per point, every iteration.
    void Add(const Eigen::Vector3d& p) {
        if (n_ == 0) ref_ = p;
        const Eigen::Vector3d d = p - ref_;
        sum_ += d;
        sum_sq_ += d * d.transpose();
        ++n_;
    }
    int count() const { return n_; }
    Eigen::Vector3d Mean() const;
    // Population covariance (divided by the count); zero for fewer than 2 points.
    Eigen::Matrix3d Covariance() const;

private:
    int n_ = 0;
    Eigen::Vector3d ref_ = Eigen::Vector3d::Zero();
    Eigen::Vector3d sum_ = Eigen::Vector3d::Zero();
    Eigen::Matrix3d sum_sq_ = Eigen::Matrix3d::Zero();
};

struct PlaneFit {
    bool valid = false;                                     // >= 3 points and a finite covariance
    Eigen::Vector3d normal = Eigen::Vector3d::Zero();       // unit, z >= 0 (pointing up)
    Eigen::Vector3d eigenvalues = Eigen::Vector3d::Zero();  // ascending, m^2
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    int count = 0;

    // The smallest eigenvalue below `ratio` times the middle one: a surface, not a line or a
    // blob (calibration uses 0.1).
    bool Planar(double ratio) const { return valid && eigenvalues[0] < ratio * eigenvalues[1]; }
};

PlaneFit FitPlane(const MomentAccumulator& m);

}  // namespace pitmap::proc::reg
