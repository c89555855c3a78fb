// SPDX-License-Identifier: MIT
#include "processor/slam/slam_math.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

namespace pitmap::proc::slam {

Eigen::Matrix3d RightJacobianInverseSO3(const Eigen::Vector3d& phi) {
    // JrInv(phi) = I + 1/2 [phi]x + (1/theta^2 - (1 + cos theta) / (2 theta sin theta)) [phi]x^2
    // (Chirikjian, Sola et al. 2018 eq. 144); the bracket tends to 1/12 as theta -> 0.
    const double theta = phi.norm();
    const Eigen::Matrix3d W = Hat(phi);
    double c;
    if (theta < 1e-4) {
        c = 1.0 / 12.0 + theta * theta / 720.0;
    } else {
        c = 1.0 / (theta * theta) - (1.0 + std::cos(theta)) / (2.0 * theta * std::sin(theta));
    }
    return Eigen::Matrix3d::Identity() + 0.5 * W + c * W * W;
}

Eigen::Matrix3d LeftJacobianInverseSO3(const Eigen::Vector3d& phi) {
    return RightJacobianInverseSO3(-phi);
}

Pose ApplyIncrement(const Pose& T, const Vector6d& delta) {
    return MakePose(ExpSO3(delta.head<3>()) * T.linear(), T.translation() + delta.tail<3>());
}

Eigen::Vector3d TransformPoint(const Pose& T_world_vehicle,
                               const Eigen::Vector3d& x_vehicle,
                               Matrix36d* J) {
    const Eigen::Vector3d Rx = T_world_vehicle.linear() * x_vehicle;
    if (J != nullptr) {
        J->leftCols<3>() = -Hat(Rx);
        J->rightCols<3>().setIdentity();
    }
    return Rx + T_world_vehicle.translation();
}

Eigen::Vector3d PointPairResidual(const Pose& T_a,
                                  const Eigen::Vector3d& x_a,
                                  const Pose& T_b,
                                  const Eigen::Vector3d& x_b,
                                  Matrix36d* J_a,
                                  Matrix36d* J_b) {
    const Eigen::Vector3d p_a = TransformPoint(T_a, x_a, J_a);
    const Eigen::Vector3d p_b = TransformPoint(T_b, x_b, J_b);
    if (J_b != nullptr) *J_b = -*J_b;
    return p_a - p_b;
}

double PointToPlaneResidual(const Pose& T_a,
                            const Eigen::Vector3d& x_a,
                            const Pose& T_b,
                            const Eigen::Vector3d& x_b,
                            const Eigen::Vector3d& normal_world,
                            Matrix16d* J_a,
                            Matrix16d* J_b) {
    Matrix36d Ja, Jb;
    const Eigen::Vector3d r = PointPairResidual(T_a, x_a, T_b, x_b, &Ja, &Jb);
    if (J_a != nullptr) *J_a = normal_world.transpose() * Ja;
    if (J_b != nullptr) *J_b = normal_world.transpose() * Jb;
    return normal_world.dot(r);
}

RelativeMotion MeasureRelativeMotion(const Pose& T_i, const Pose& T_j) {
    RelativeMotion m;
    m.R_world = T_j.linear() * T_i.linear().transpose();
    m.d_i_m = T_i.linear().transpose() * (T_j.translation() - T_i.translation());
    return m;
}

Vector6d RelativeMotionResidual(const Pose& T_i,
                                const Pose& T_j,
                                const RelativeMotion& measured,
                                Matrix6d* J_i,
                                Matrix6d* J_j) {
    const Eigen::Matrix3d& Ri = T_i.linear();
    const Eigen::Matrix3d& Rj = T_j.linear();
    const Eigen::Matrix3d& Q = measured.R_world;
    const Eigen::Vector3d v = T_j.translation() - T_i.translation();
    Vector6d r;
    r.head<3>() = LogSO3(Rj * Ri.transpose() * Q.transpose());
    r.tail<3>() = Ri.transpose() * v - measured.d_i_m;
    // Perturbing R_j on the left: E -> Exp(b) E, so dr/db = JlInv(r). Perturbing R_i:
    // E -> R_j R_i^T Exp(-a) Q^T = E Exp(-Q a), so dr/da = -JrInv(r) Q.
    // Translation: R_i^T Exp(-a) v ~= R_i^T (v + [v]x a), so d/da = R_i^T [v]x.
    if (J_i != nullptr) {
        J_i->setZero();
        J_i->topLeftCorner<3, 3>() = -RightJacobianInverseSO3(r.head<3>()) * Q;
        J_i->bottomLeftCorner<3, 3>() = Ri.transpose() * Hat(v);
        J_i->bottomRightCorner<3, 3>() = -Ri.transpose();
    }
    if (J_j != nullptr) {
        J_j->setZero();
        J_j->topLeftCorner<3, 3>() = LeftJacobianInverseSO3(r.head<3>());
        J_j->bottomRightCorner<3, 3>() = Ri.transpose();
    }
    return r;
}

Vector6d AbsolutePoseResidual(const Pose& T, const Pose& T_prior, Matrix6d* J) {
    Vector6d r;
    r.head<3>() = LogSO3(T.linear() * T_prior.linear().transpose());
    r.tail<3>() = T.translation() - T_prior.translation();
    if (J != nullptr) {
        J->setZero();
        J->topLeftCorner<3, 3>() = LeftJacobianInverseSO3(r.head<3>());
        J->bottomRightCorner<3, 3>().setIdentity();
    }
    return r;
}

Eigen::Vector3d PositionWhiteNoise(const std::vector<double>& t_s,
                                   const std::vector<Pose>& T,
                                   double max_step_s,
                                   std::size_t min_triples) {
    std::array<std::vector<double>, 3> z2;
    for (std::size_t k = 1; k + 1 < std::min(t_s.size(), T.size()); ++k) {
        const double dt0 = t_s[k] - t_s[k - 1], dt1 = t_s[k + 1] - t_s[k];
        if (!(dt0 > 0 && dt1 > 0 && dt0 <= max_step_s && dt1 <= max_step_s)) continue;
        if (std::max(dt0, dt1) > 1.5 * std::min(dt0, dt1)) continue;
        const Eigen::Vector3d r = (T[k + 1].translation() - T[k].translation()) / dt1 -
                                  (T[k].translation() - T[k - 1].translation()) / dt0;
        const double w2 = 1.0 / (dt0 * dt0) + 1.0 / (dt1 * dt1) +
                          (1.0 / dt0 + 1.0 / dt1) * (1.0 / dt0 + 1.0 / dt1);
        for (int c = 0; c < 3; ++c) z2[static_cast<std::size_t>(c)].push_back(r(c) * r(c) / w2);
    }
    Eigen::Vector3d sigma = Eigen::Vector3d::Zero();
    if (z2[0].size() < std::max<std::size_t>(min_triples, 1)) return sigma;
    constexpr double kChi2Median = 0.454936;  // median of a chi-square with 1 degree of freedom
    for (int c = 0; c < 3; ++c) {
        std::vector<double>& v = z2[static_cast<std::size_t>(c)];
        const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
        std::nth_element(v.begin(), mid, v.end());
        sigma(c) = std::sqrt(*mid / kChi2Median);
    }
    return sigma;
}

}  // namespace pitmap::proc::slam
