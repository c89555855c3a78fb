// SPDX-License-Identifier: MIT
// The SLAM parametrisation and the terms of its normal equations.
//   Pairs: the n-scan ICP error of the seed paper (eq. 2), E = sum_{j->k} sum_i
//     |R_j m_i + t_j - (R_k d_i + t_k)|^2, here per sounding pair between slices, with the
//     point-to-plane or GICP information instead of the identity (a Mahalanobis form as in
//     eq. 3, Borrmann et al. 2008) and a robust kernel; slice poses interpolate between nodes
//     (Elseberg et al. 2013), so a pair's Jacobian spreads over up to four nodes.
//   INS: relative motion between consecutive nodes, drift smoothness, absolute priors.
// Each term adds J^T W J and J^T W r to a reg::BlockSystem<6> (processor/registration).
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "processor/registration/correspondence.hpp"
#include "processor/registration/robust.hpp"
#include "processor/slam/internal.hpp"

namespace pitmap::proc::slam::detail {

void SliceCorrection(const Param& p, std::size_t s, Eigen::Matrix3d* R, Eigen::Vector3d* t) {
    const int a = p.k0[s];
    const double w = p.alpha[s];
    if (w == 0.0) {
        *R = p.Rc[a];
        *t = p.tc[a];
        return;
    }
    const int b = p.k1[s];
    *R = ExpSO3((1.0 - w) * LogSO3(p.Rc[a]) + w * LogSO3(p.Rc[b]));
    *t = (1.0 - w) * p.tc[a] + w * p.tc[b];
}

std::vector<Pose> SlicePoses(const Param& p) {
    std::vector<Pose> out(p.base.size());
    tbb::parallel_for(std::size_t{0}, p.base.size(), [&](std::size_t s) {
        Eigen::Matrix3d R;
        Eigen::Vector3d t;
        SliceCorrection(p, s, &R, &t);
        out[s] = MakePose(R * p.base[s].linear(),
                          R * (p.base[s].translation() - p.pivot[s]) + p.pivot[s] + t);
    });
    return out;
}

// d(slice pose perturbation) / d(node increment), times the interpolation weight w.
Matrix6d NodeToSlice(const Param& p, const Pose& T_s, std::size_t s, double w) {
    Eigen::Matrix3d R;
    Eigen::Vector3d t;
    SliceCorrection(p, s, &R, &t);
    Matrix6d G = Matrix6d::Zero();
    G.topLeftCorner<3, 3>().setIdentity();
    G.bottomRightCorner<3, 3>().setIdentity();
    G.bottomLeftCorner<3, 3>() = -Hat(T_s.translation() - p.pivot[s] - t);
    return w * G;
}

Param MakeParam(const std::vector<Pose>& base, const std::vector<std::size_t>& node_start) {
    Param p;
    const std::size_t ns = base.size();
    p.base = base;
    p.pivot.resize(ns);
    p.k0.resize(ns);
    p.k1.resize(ns);
    p.alpha.assign(ns, 0.0);
    for (std::size_t k = 0; k < node_start.size(); ++k) {
        p.anchor.push_back(static_cast<int>(node_start[k]));
    }
    p.Rc.assign(node_start.size(), Eigen::Matrix3d::Identity());
    p.tc.assign(node_start.size(), Eigen::Vector3d::Zero());
    return p;
}

namespace {

// The slice's dependence on nodes: (node, weight) pairs.
int SliceNodes(const Param& p, std::size_t s, int* nodes, double* w) {
    nodes[0] = p.k0[s];
    w[0] = 1.0 - p.alpha[s];
    if (p.alpha[s] == 0.0) {
        w[0] = 1.0;
        return 1;
    }
    nodes[1] = p.k1[s];
    w[1] = p.alpha[s];
    return 2;
}

Vector6d SigmaVector(const Vector6d& ins, double scale) {
    Vector6d s;
    const double att_h = std::max(ins(0), ins(1));
    const double pos_h = std::max(ins(3), ins(4));
    s << att_h, att_h, ins(2), pos_h, pos_h, ins(5);
    return s * scale;
}

// The square root of the steady part's share of a position's INS variance, f^2 / (f^2 + g^2),
// by which the relative-motion and absolute position terms' information is scaled in an
// outage (SlamConfig::drift_by_smoothness_only): the growing part g is one drift, which the
// drift-smoothness term states; 1 where there is none.
double SteadyShare(double floor2, double growing, const SlamConfig& cfg) {
    if (!cfg.drift_by_smoothness_only || !(growing > 0)) return 1.0;
    if (!(floor2 > 0)) return 1e-6;  // no steady part: the drift alone (a tiny weight)
    return std::max(std::sqrt(floor2 / (floor2 + growing * growing)), 1e-6);
}

}  // namespace

// Relative-motion and absolute terms (no pairs).
// With linearise false only acc.cost is accumulated (the step acceptance test).
void AddPoseTerms(const Input& in,
                  const Param& p,
                  const std::vector<Pose>& T,
                  const SlamConfig& cfg,
                  bool linearise,
                  Terms& acc) {
    const std::size_t n = p.num_nodes();
    for (std::size_t k = 0; k + 1 < n; ++k) {
        const auto i = static_cast<std::size_t>(p.anchor[k]);
        const auto j = static_cast<std::size_t>(p.anchor[k + 1]);
        const RelativeMotion m = MeasureRelativeMotion(in.T_ins[i], in.T_ins[j]);
        Matrix6d Ji, Jj;
        const Vector6d r = RelativeMotionResidual(T[i], T[j], m, &Ji, &Jj);
        const double dt = std::abs(in.t_s[j] - in.t_s[i]);
        // Steady part: a Gauss-Markov error of the survey's smallest sigma; growing part (dead
        // reckoning): its increment is about the change of the sigma above that floor.
        const double f2 = std::min(1.0, 2.0 * dt / cfg.ins_correlation_time_s);
        Vector6d raw;
        for (int c = 0; c < 6; ++c) {
            const double fl2 = in.sigma_floor(c) * in.sigma_floor(c);
            const double gi = std::sqrt(std::max(0.0, in.sigma[i](c) * in.sigma[i](c) - fl2));
            const double gj = std::sqrt(std::max(0.0, in.sigma[j](c) * in.sigma[j](c) - fl2));
            raw(c) = std::sqrt(fl2 * f2 + (gj - gi) * (gj - gi));
            if (c >= 3) raw(c) /= SteadyShare(fl2, std::max(gi, gj), cfg);
        }
        Vector6d sig = SigmaVector(raw, cfg.ins_sigma_scale);
        for (int c = 0; c < 3; ++c) sig(c) = std::max(sig(c), cfg.min_relative_rotation_sigma_rad);
        for (int c = 3; c < 6; ++c) {
            sig(c) = std::max(sig(c), cfg.min_relative_translation_sigma_m);
        }
        const Matrix6d W = sig.cwiseInverse().cwiseAbs2().asDiagonal();
        acc.cost += r.dot(W * r);
        if (!linearise) continue;
        const int nodes[2] = {static_cast<int>(k), static_cast<int>(k + 1)};
        const Matrix6d J[2] = {Ji * NodeToSlice(p, T[i], i, 1.0),
                               Jj * NodeToSlice(p, T[j], j, 1.0)};
        acc.sys.Add<6>(nodes, J, 2, W, r);
    }
    // Drift smoothness: the INS's position error e = t - t_ins changes its rate (the velocity
    // error) by a random walk, so (e_2 - e_1) / dt_1 - (e_1 - e_0) / dt_0 ~ N(0, q^2 dt) per axis,
    // loosened where the INS sigma falls (a filter pulling its drift back after an outage).
    const double q = cfg.drift_velocity_random_walk_mps_per_sqrt_s;
    if (q > 0) {
        for (std::size_t k = 1; k + 1 < n; ++k) {
            std::size_t a[3];
            Eigen::Vector3d e[3];
            Eigen::Matrix<double, 3, 6> B[3];
            for (int m = 0; m < 3; ++m) {
                a[m] = static_cast<std::size_t>(p.anchor[k + static_cast<std::size_t>(m) - 1]);
                e[m] = T[a[m]].translation() - in.T_ins[a[m]].translation();
                B[m] = NodeToSlice(p, T[a[m]], a[m], 1.0).bottomRows<3>();
            }
            const double d0 = std::max(in.t_s[a[1]] - in.t_s[a[0]], 1e-3);
            const double d1 = std::max(in.t_s[a[2]] - in.t_s[a[1]], 1e-3);
            const Eigen::Vector3d r = (e[2] - e[1]) / d1 - (e[1] - e[0]) / d0;
            const double dm = 0.5 * (d0 + d1);
            Eigen::Matrix3d W = Eigen::Matrix3d::Zero();
            for (int c = 0; c < 3; ++c) {
                const double fall =
                    std::max(0.0, in.sigma[a[0]](3 + c) - in.sigma[a[2]](3 + c)) / dm;
                W(c, c) = 1.0 / (q * q * dm + fall * fall);
            }
            acc.cost += r.dot(W * r);
            if (!linearise) continue;
            const int nodes[3] = {
                static_cast<int>(k - 1), static_cast<int>(k), static_cast<int>(k + 1)};
            const Matrix36d J[3] = {B[0] / d0, -(1.0 / d1 + 1.0 / d0) * B[1], B[2] / d1};
            acc.sys.Add<3>(nodes, J, 3, W, r);
        }
    }
    const bool abs_any = cfg.absolute_position_terms || cfg.absolute_attitude_terms;
    for (std::size_t k = 0; k < n; ++k) {
        const auto i = static_cast<std::size_t>(p.anchor[k]);
        Matrix6d Ja;
        const Vector6d r = AbsolutePoseResidual(T[i], in.T_ins[i], &Ja);
        Vector6d info = Vector6d::Zero();
        if (abs_any) {
            // The scale applies to the steady part of the sigma (the survey's smallest, what
            // the INS holds with GNSS); the part above it (an outage's drift) is as reported.
            Vector6d scaled;
            for (int c = 0; c < 6; ++c) {
                const double fl = in.sigma_floor(c);  // <= in.sigma[i](c): the survey's minimum
                const double growing2 = std::max(0.0, in.sigma[i](c) * in.sigma[i](c) - fl * fl);
                const double st = cfg.absolute_sigma_scale * fl;
                scaled(c) = std::sqrt(st * st + growing2);
                if (c >= 3) scaled(c) /= SteadyShare(fl * fl, std::sqrt(growing2), cfg);
            }
            const Vector6d sig = SigmaVector(scaled, 1.0);
            if (cfg.absolute_attitude_terms)
                info.head<3>() = sig.head<3>().cwiseInverse().cwiseAbs2();
            if (cfg.absolute_position_terms)
                info.tail<3>() = sig.tail<3>().cwiseInverse().cwiseAbs2();
        } else if (k == 0) {
            info.setConstant(1e8);  // gauge: the first pose stays where the INS put it
        }
        if (info.isZero()) continue;
        const Matrix6d W = info.asDiagonal();
        acc.cost += r.dot(W * r);
        if (!linearise) continue;
        const int nodes[1] = {static_cast<int>(k)};
        const Matrix6d J[1] = {Ja * NodeToSlice(p, T[i], i, 1.0)};
        acc.sys.Add<6>(nodes, J, 1, W, r);
    }
}

// Pair terms; with linearise false only the robust cost (and sq_dist) are accumulated.
void AddPairTerms(const Input& in,
                  const Param& p,
                  const std::vector<Pose>& T,
                  const std::vector<Pair>& pairs,
                  const SlamConfig& cfg,
                  bool linearise,
                  tbb::enumerable_thread_specific<Terms>& accs,
                  PairInformation information,
                  double weight_scale) {
    const double s2 = cfg.point_sigma_m * cfg.point_sigma_m;
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, pairs.size(), 1024),
        [&](const tbb::blocked_range<std::size_t>& range) {
            Terms& acc = accs.local();
            for (std::size_t k = range.begin(); k != range.end(); ++k) {
                const Pair& pr = pairs[k];
                const std::size_t a = pr.slice_a, b = pr.slice_b;
                const Eigen::Vector3d xa = in.points[pr.c.query].cast<double>();
                const Eigen::Vector3d xb = in.points[pr.c.target].cast<double>();
                Matrix36d Ja, Jb;
                const Eigen::Vector3d r3 = linearise
                                               ? PointPairResidual(T[a], xa, T[b], xb, &Ja, &Jb)
                                               : PointPairResidual(T[a], xa, T[b], xb);
                int nodes[4];
                double w[4];
                const int na = SliceNodes(p, a, nodes, w);
                const int nb = SliceNodes(p, b, nodes + na, w + na);
                const int count = na + nb;
                acc.sq_dist += r3.squaredNorm();
                const bool plane = cfg.correspondence == CorrespondenceType::kPointToPlane;
                if (plane || information == PairInformation::kNormalOnly) {
                    // Point-to-plane: the target's normal, the target's noise. Normal only:
                    // the mean of both normals, both points' noise (GICP's normal direction).
                    Eigen::Vector3d nrm = pr.c.target_normal.cast<double>();
                    double sigma = cfg.point_sigma_m;
                    if (!plane) {
                        const Eigen::Vector3d na3 = pr.c.query_normal.cast<double>();
                        nrm += na3.dot(nrm) < 0 ? -na3 : na3;
                        if (nrm.norm() < 1e-9) nrm = pr.c.target_normal.cast<double>();
                        nrm.normalize();
                        sigma *= std::sqrt(2.0);
                    }
                    Eigen::Matrix<double, 1, 1> r;
                    r(0) = nrm.dot(r3);
                    const double sw = std::abs(r(0)) / sigma;
                    acc.cost += RobustCost(cfg.robust_kernel, sw, cfg.robust_width);
                    if (!linearise) continue;
                    Eigen::Matrix<double, 1, 1> W;
                    W(0) = weight_scale * RobustWeight(cfg.robust_kernel, sw, cfg.robust_width) /
                           (sigma * sigma);
                    Matrix16d J[4];
                    for (int i = 0; i < count; ++i) {
                        const bool is_a = i < na;
                        const std::size_t s = is_a ? a : b;
                        J[i] = nrm.transpose() * (is_a ? Ja : Jb) * NodeToSlice(p, T[s], s, w[i]);
                    }
                    acc.sys.Add<1>(nodes, J, count, W, r);
                } else {
                    Eigen::Matrix3d info;
                    if (cfg.correspondence == CorrespondenceType::kGicp) {
                        const Eigen::Vector3d na3 = pr.c.query_normal.cast<double>();
                        const Eigen::Vector3d nb3 = pr.c.target_normal.cast<double>();
                        info = reg::GicpInformation(
                            na3, nb3, cfg.point_sigma_m, cfg.gicp_tangent_sigma_m);
                    } else {
                        info = Eigen::Matrix3d::Identity() / s2;
                    }
                    const double m2 = r3.dot(info * r3);
                    const double sw = std::sqrt(m2);
                    acc.cost += RobustCost(cfg.robust_kernel, sw, cfg.robust_width);
                    if (!linearise) continue;
                    const Eigen::Matrix3d W =
                        weight_scale * RobustWeight(cfg.robust_kernel, sw, cfg.robust_width) * info;
                    Matrix36d J[4];
                    for (int i = 0; i < count; ++i) {
                        const bool is_a = i < na;
                        const std::size_t s = is_a ? a : b;
                        J[i] = (is_a ? Ja : Jb) * NodeToSlice(p, T[s], s, w[i]);
                    }
                    acc.sys.Add<3>(nodes, J, count, W, r3);
                }
            }
        });
}

// Total cost (INS terms and robust pair terms) of the parametrisation p on fixed pairs.
double CostAt(const Input& in,
              const Param& p,
              const std::vector<Pair>& pairs,
              const SlamConfig& cfg) {
    const std::vector<Pose> T = SlicePoses(p);
    Terms pose_terms(0);
    AddPoseTerms(in, p, T, cfg, /*linearise=*/false, pose_terms);
    tbb::enumerable_thread_specific<Terms> accs([] { return Terms(0); });
    AddPairTerms(in, p, T, pairs, cfg, /*linearise=*/false, accs);
    double cost = pose_terms.cost;
    for (const Terms& acc : accs) cost += acc.cost;
    return cost;
}

}  // namespace pitmap::proc::slam::detail
