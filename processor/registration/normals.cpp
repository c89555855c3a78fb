// SPDX-License-Identifier: MIT
#include "processor/registration/normals.hpp"

#include <Eigen/Eigenvalues>

namespace pitmap::proc::reg {

Eigen::Vector3d MomentAccumulator::Mean() const {
    return n_ > 0 ? Eigen::Vector3d(ref_ + Eigen::Vector3d(sx_, sy_, sz_) / n_)
                  : Eigen::Vector3d::Zero();
}

Eigen::Matrix3d MomentAccumulator::Covariance() const {
    if (n_ < 2) return Eigen::Matrix3d::Zero();
    const Eigen::Vector3d m = Eigen::Vector3d(sx_, sy_, sz_) / n_;
    Eigen::Matrix3d sq;
    sq << sxx_, sxy_, sxz_, sxy_, syy_, syz_, sxz_, syz_, szz_;
    return sq / n_ - m * m.transpose();
}

PlaneFit FitPlane(const MomentAccumulator& m) {
    PlaneFit f;
    f.count = m.count();
    f.mean = m.Mean();
    if (m.count() < 3) return f;
    const Eigen::Matrix3d C = m.Covariance();
    if (!C.allFinite()) return f;
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(C);
    if (es.info() != Eigen::Success) return f;
    f.eigenvalues = es.eigenvalues();
    f.normal = es.eigenvectors().col(0);
    if (f.normal.z() < 0) f.normal = -f.normal;
    f.valid = true;
    return f;
}

}  // namespace pitmap::proc::reg
