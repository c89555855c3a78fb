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
    // Inline: calibration and SLAM add tens of neighbours per point, every iteration. The six
    // distinct second moments are plain doubles, so they stay in registers: an Eigen outer
    // product here went through a temporary on the stack, and the loads that read it back
    // stalled on the stores (half of calibration's pair search). Same sums, same order.
    void Add(const Eigen::Vector3d& p) {
        if (n_ == 0) ref_ = p;
        const double x = p.x() - ref_.x(), y = p.y() - ref_.y(), z = p.z() - ref_.z();
        sx_ += x;
        sy_ += y;
        sz_ += z;
        sxx_ += x * x;
        sxy_ += x * y;
        sxz_ += x * z;
        syy_ += y * y;
        syz_ += y * z;
        szz_ += z * z;
        ++n_;
    }
    int count() const { return n_; }
    Eigen::Vector3d Mean() const;
    // Population covariance (divided by the count); zero for fewer than 2 points.
    Eigen::Matrix3d Covariance() const;

private:
    int n_ = 0;
    Eigen::Vector3d ref_ = Eigen::Vector3d::Zero();
    double sx_ = 0, sy_ = 0, sz_ = 0;                                   // sums of p - ref
    double sxx_ = 0, sxy_ = 0, sxz_ = 0, syy_ = 0, syz_ = 0, szz_ = 0;  // and of their products
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
