// SPDX-License-Identifier: MIT
#include "common/se3.hpp"

#include <algorithm>
#include <cmath>

namespace pitmap {

Eigen::Matrix3d Hat(const Eigen::Vector3d& v) {
    Eigen::Matrix3d m;
    m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
    return m;
}

Eigen::Matrix3d ExpSO3(const Eigen::Vector3d& omega) {
    const double theta2 = omega.squaredNorm();
    const Eigen::Matrix3d W = Hat(omega);
    double a, b;  // R = I + a W + b W^2 (Rodrigues)
    if (theta2 < 1e-10) {
        // Taylor series: sin t / t = 1 - t^2/6, (1 - cos t) / t^2 = 1/2 - t^2/24.
        a = 1.0 - theta2 / 6.0;
        b = 0.5 - theta2 / 24.0;
    } else {
        const double theta = std::sqrt(theta2);
        a = std::sin(theta) / theta;
        b = (1.0 - std::cos(theta)) / theta2;
    }
    return Eigen::Matrix3d::Identity() + a * W + b * W * W;
}

Eigen::Vector3d LogSO3(const Eigen::Matrix3d& R) {
    // The quaternion route is well conditioned everywhere, including angles near pi,
    // where the trace formula loses the axis.
    Eigen::Quaterniond q(R);
    q.normalize();
    if (q.w() < 0) q.coeffs() *= -1.0;  // angle in [0, pi]
    const double vnorm = q.vec().norm();
    if (vnorm < 1e-12) {
        return 2.0 * q.vec();  // first order: theta ~ 2 |v|
    }
    const double theta = 2.0 * std::atan2(vnorm, q.w());
    return q.vec() * (theta / vnorm);
}

double RotationAngleBetween(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
    return LogSO3(a.transpose() * b).norm();
}

Eigen::Quaterniond SlerpShortest(const Eigen::Quaterniond& a,
                                 const Eigen::Quaterniond& b,
                                 double alpha) {
    Eigen::Quaterniond bb = b;
    if (a.dot(b) < 0) bb.coeffs() *= -1.0;
    // q(alpha) = a * exp(alpha * log(a^-1 b)); valid for extrapolation too.
    const Eigen::Matrix3d delta = (a.conjugate() * bb).toRotationMatrix();
    const Eigen::Vector3d w = LogSO3(delta) * alpha;
    Eigen::Quaterniond out = a * Eigen::Quaterniond(ExpSO3(w));
    out.normalize();
    return out;
}

Pose InterpolatePose(const Pose& a, const Pose& b, double alpha) {
    const Eigen::Quaterniond qa(a.linear());
    const Eigen::Quaterniond qb(b.linear());
    const Eigen::Quaterniond q = SlerpShortest(qa, qb, alpha);
    return MakePose(q.toRotationMatrix(),
                    (1.0 - alpha) * a.translation() + alpha * b.translation());
}

Pose MakePose(const Eigen::Matrix3d& R, const Eigen::Vector3d& t) {
    Pose T = Pose::Identity();
    T.linear() = R;
    T.translation() = t;
    return T;
}

}  // namespace pitmap
