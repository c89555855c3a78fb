// SPDX-License-Identifier: MIT
// The posterior of the semi-rigid SLAM result (SlamPosterior in slam.hpp): marginal
// covariances of the pose nodes' corrections from the undamped normal equations at the kept
// iterate, scaled by the a-posteriori variance factor, and interpolated to the slices.
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <utility>

#include "processor/slam/internal.hpp"

namespace pitmap::proc::slam::detail {

namespace {

// Residual rows of the pose terms, as AddPoseTerms adds them.
double PoseTermRows(std::size_t n, const SlamConfig& cfg) {
    double rows = n > 1 ? 6.0 * static_cast<double>(n - 1) : 0.0;  // relative motion
    if (cfg.drift_velocity_random_walk_mps_per_sqrt_s > 0 && n > 2) {
        rows += 3.0 * static_cast<double>(n - 2);  // drift smoothness
    }
    if (cfg.absolute_position_terms || cfg.absolute_attitude_terms) {
        const double per =
            (cfg.absolute_attitude_terms ? 3.0 : 0.0) + (cfg.absolute_position_terms ? 3.0 : 0.0);
        rows += per * static_cast<double>(n);
    } else if (n > 0) {
        rows += 6.0;  // the gauge prior on the first node
    }
    return rows;
}

// 1-sigma roll, pitch, yaw of a world-frame rotation covariance at attitude R (FRD vehicle
// in ENU): the perturbation dphi = a_roll droll + a_pitch dpitch + a_yaw dyaw with the axes of
// hydro::SoundingCovariance (vehicle x; horizontal, across the heading; vertical).
Eigen::Vector3d RollPitchYawSigma(const Eigen::Matrix3d& R, const Eigen::Matrix3d& C) {
    const Eigen::Vector3d a_roll = R.col(0);
    const Eigen::Vector3d down(0, 0, -1);
    Eigen::Vector3d h(a_roll.x(), a_roll.y(), 0.0);
    if (h.norm() < 1e-6) h = Eigen::Vector3d::UnitX();  // pointing straight down: any heading
    h.normalize();
    Eigen::Matrix3d A;
    A.col(0) = a_roll;
    A.col(1) = down.cross(h);
    A.col(2) = down;
    const Eigen::Matrix3d Ai = A.inverse();
    const Eigen::Matrix3d Crpy = Ai * C * Ai.transpose();
    return Crpy.diagonal().cwiseMax(0.0).cwiseSqrt();
}

using Clusters = std::map<std::pair<std::uint32_t, std::uint32_t>, std::vector<Pair>>;

// The pairs grouped by the pair of rigid sections (blocks) they join.
Clusters ClusterPairs(const std::vector<Pair>& pairs) {
    Clusters clusters;
    for (const Pair& pr : pairs) {
        clusters[{std::min(pr.block_a, pr.block_b), std::max(pr.block_a, pr.block_b)}].push_back(
            pr);
    }
    return clusters;
}

// The intra-cluster correlation of the pairs' residuals along their normals (the mean of both
// normals, oriented upwards: the sonar sees surfaces from above), by the one-way analysis of
// variance (Fisher's intraclass correlation, the ANOVA estimator):
//   rho = (MSB - MSW) / (MSB + (n0 - 1) MSW), n0 = (N - sum n_c^2 / N) / (C - 1),
// with MSB and MSW the between- and within-cluster mean squares; clamped to [0, 1]. Residuals
// beyond the robust kernel's width (wrong pairs) are left out.
double ResidualCorrelation(const Input& in,
                           const std::vector<Pose>& T,
                           const Clusters& clusters,
                           const SlamConfig& cfg) {
    const double limit = cfg.robust_width * std::sqrt(2.0) * cfg.point_sigma_m;
    std::vector<std::vector<double>> r(clusters.size());
    std::size_t c = 0;
    for (const auto& [key, prs] : clusters) {
        for (const Pair& pr : prs) {
            Eigen::Vector3d n = pr.c.target_normal.cast<double>();
            const Eigen::Vector3d na = pr.c.query_normal.cast<double>();
            n += na.dot(n) < 0 ? -na : na;
            if (n.norm() < 1e-9) continue;
            n.normalize();
            if (n.z() < 0) n = -n;
            const double rn = n.dot(PointPairResidual(T[pr.slice_a],
                                                      in.points[pr.c.query].cast<double>(),
                                                      T[pr.slice_b],
                                                      in.points[pr.c.target].cast<double>()));
            if (std::abs(rn) <= limit) r[c].push_back(rn);
        }
        ++c;
    }
    double total = 0, n_all = 0, sum_n2 = 0, groups = 0;
    for (const auto& v : r) {
        if (v.size() < 2) continue;
        for (double x : v) total += x;
        n_all += static_cast<double>(v.size());
        sum_n2 += static_cast<double>(v.size() * v.size());
        groups += 1;
    }
    if (groups < 2 || n_all <= groups) return 0.0;
    const double mean = total / n_all;
    double ssb = 0, ssw = 0;
    for (const auto& v : r) {
        if (v.size() < 2) continue;
        double m = 0;
        for (double x : v) m += x;
        m /= static_cast<double>(v.size());
        ssb += static_cast<double>(v.size()) * (m - mean) * (m - mean);
        for (double x : v) ssw += (x - m) * (x - m);
    }
    const double msb = ssb / (groups - 1), msw = ssw / (n_all - groups);
    const double n0 = (n_all - sum_n2 / n_all) / (groups - 1);
    const double den = msb + (n0 - 1) * msw;
    return den > 0 ? std::clamp((msb - msw) / den, 0.0, 1.0) : 0.0;
}

// The share of a cluster's pair information that is independent: n pairs whose errors
// correlate by rho inform as n / (1 + (n - 1) rho) independent ones (the design effect).
double ClusterWeight(std::size_t n, double rho) {
    return 1.0 / (1.0 + (static_cast<double>(n) - 1.0) * rho);
}

// Adds H^-1 M H^-1 (SlamPosterior) to the node blocks Ckk (k, k) and Ckn (k, k + 1): the
// pairs clustered by section pair, each cluster's gradient g_c, Y = H^-1 G in batches.
bool AddClusterRobust(const Input& in,
                      const Param& p,
                      const std::vector<Pose>& T,
                      const Clusters& clusters,
                      double rho,
                      const SlamConfig& cfg,
                      PairInformation pair_info,
                      reg::DampedSolver<6>& ne,
                      std::vector<Matrix6d>& Ckk,
                      std::vector<Matrix6d>& Ckn,
                      std::size_t* num_clusters) {
    const std::size_t n = p.num_nodes();
    *num_clusters = clusters.size();
    const auto dim = static_cast<Eigen::Index>(6 * n);
    const std::size_t batch = static_cast<std::size_t>(std::max(1, cfg.posterior_batch_nodes)) * 6;
    auto it = clusters.begin();
    while (it != clusters.end()) {
        std::vector<Eigen::VectorXd> cols;
        for (; it != clusters.end() && cols.size() < batch; ++it) {
            tbb::enumerable_thread_specific<Terms> accs([n] { return Terms(n); });
            AddPairTerms(in,
                         p,
                         T,
                         it->second,
                         cfg,
                         /*linearise=*/true,
                         accs,
                         pair_info,
                         ClusterWeight(it->second.size(), rho));
            Eigen::VectorXd g = Eigen::VectorXd::Zero(dim);
            for (const Terms& acc : accs) {
                const auto& grad = acc.sys.grad();
                for (std::size_t k = 0; k < n; ++k) {
                    g.segment<6>(static_cast<Eigen::Index>(6 * k)) += grad[k];
                }
            }
            cols.push_back(std::move(g));
        }
        Eigen::MatrixXd G(dim, static_cast<Eigen::Index>(cols.size()));
        for (std::size_t c = 0; c < cols.size(); ++c) G.col(static_cast<Eigen::Index>(c)) = cols[c];
        const Eigen::MatrixXd Y = ne.SolveMany(G);
        if (Y.size() == 0) return false;
        for (std::size_t k = 0; k < n; ++k) {
            const auto o = static_cast<Eigen::Index>(6 * k);
            const Eigen::MatrixXd Yk = Y.middleRows(o, 6);
            Ckk[k] += Yk * Yk.transpose();
            if (k + 1 < n) Ckn[k] += Yk * Y.middleRows(o + 6, 6).transpose();
        }
    }
    return true;
}

// The pairs at the kept iterate (the stage's timings stay the stage's).
std::vector<Pair> PairsAtKeptIterate(const Input& in,
                                     const std::vector<Pose>& T,
                                     std::vector<Block>& blocks,
                                     const std::vector<std::uint32_t>& slice_block,
                                     const SlamConfig& cfg,
                                     SlamResult& res) {
    const SlamTimings stage_timings = res.timings;
    std::vector<Eigen::Vector3f> pw(in.points.size());
    Search found = SearchPairs(
        in, T, SlamStage::kSemiRigid, cfg.max_pair_distance_m, blocks, slice_block, pw, cfg, res);
    res.timings = stage_timings;
    return std::move(found.pairs);
}

// The posterior's normal equations at the kept iterate: the pose terms and the pairs, each
// cluster's pairs scaled by the design effect with the residuals' correlation `rho`.
Terms PosteriorTerms(const Input& in,
                     const Param& p,
                     const std::vector<Pose>& T,
                     const Clusters& clusters,
                     double rho,
                     PairInformation pair_info,
                     const SlamConfig& cfg) {
    const std::size_t n = p.num_nodes();
    Terms total(n);
    AddPoseTerms(in, p, T, cfg, /*linearise=*/true, total);
    tbb::enumerable_thread_specific<Terms> accs([n] { return Terms(n); });
    for (const auto& [key, prs] : clusters) {
        AddPairTerms(in,
                     p,
                     T,
                     prs,
                     cfg,
                     /*linearise=*/true,
                     accs,
                     pair_info,
                     ClusterWeight(prs.size(), rho));
    }
    for (const Terms& acc : accs) {
        total.sys.Merge(acc.sys);
        total.cost += acc.cost;
    }
    return total;
}

// sigma0^2: the robust cost (sum of whitened squared residuals, Huber beyond its width)
// over the redundancy. A pair counts one row for point-to-plane and GICP (GICP's along-
// surface sigma is a deliberately loose bound, not a measurement error: its two rows carry
// almost no weight and would only dilute the factor), three for point-to-point. Sets the
// observations, unknowns and variance factor of `post`; returns the scale of the covariances
// (not finite and positive without redundancy).
double CovarianceScale(
    std::size_t n, std::size_t num_pairs, double cost, const SlamConfig& cfg, SlamPosterior& post) {
    const double pair_rows = cfg.correspondence == CorrespondenceType::kPointToPoint ? 3.0 : 1.0;
    post.observations = PoseTermRows(n, cfg) + pair_rows * static_cast<double>(num_pairs);
    post.unknowns = 6.0 * static_cast<double>(n);
    const double redundancy = post.observations - post.unknowns;
    post.variance_factor =
        redundancy > 0 ? cost / redundancy : std::numeric_limits<double>::quiet_NaN();
    return cfg.posterior_cluster_robust    ? 1.0
           : cfg.posterior_variance_factor ? post.variance_factor
                                           : 1.0;
}

// The median over the nodes of the formal horizontal sigma (unscaled), for the record.
double FormalHorizontalMedian(const std::vector<Matrix6d>& Ckk, double scale) {
    std::vector<double> h;
    for (const Matrix6d& Ck : Ckk) {
        const Matrix6d C = Ck / scale;
        h.push_back(std::sqrt(std::max(0.0, 0.5 * (C(3, 3) + C(4, 4)))));
    }
    std::nth_element(h.begin(), h.begin() + static_cast<std::ptrdiff_t>(h.size() / 2), h.end());
    return h[h.size() / 2];
}

// Whether the pair's slices depend only on nodes [first, last) of p.
bool PairInWindow(const Param& p, const Pair& pr, std::size_t first, std::size_t last) {
    for (const std::uint32_t s : {pr.slice_a, pr.slice_b}) {
        for (const int k : {p.k0[s], p.k1[s]}) {
            const auto u = static_cast<std::size_t>(k);
            if (u < first || u >= last) return false;
        }
    }
    return true;
}

// ---- the INS's steady position error through the rigid stage's result (decision 042) -------
// The INS's steady position error (the survey's smallest sigma f per axis, what it holds with
// GNSS) is a first-order Gauss-Markov process of correlation time tau
// (SlamConfig::ins_correlation_time_s). Where GNSS is good the semi-rigid stage's iterates
// usually score worse than the rigid stage's result, and the stage keeps its start (bejanca:
// both semi-rigid iterates worse, the rigid result kept): SLAM's result is then the rigid
// stage's, an estimator whose absolute terms are one per section (15 s) against every pair of
// the section, and whose result errs much less than f (bejanca: the INS 14.4 mm vertically, the
// result 9.2 mm with the INS's 5 mm white noise, uncorrelated between passes minutes apart).
// The result's error at slice s is the INS's error there, e_s, plus the correction the rigid
// estimator made of it: with the node increments xi = -H_r^-1 (g(e) - g(0)) (H_r the rigid
// stage's normal equations at the result, its pairs at the solver's weights; g the pose terms'
// gradient with the INS positions at the nodes' anchors moved by e) the correction at s is
// xi(s) - e_i(s), xi(s) the slice's interpolation of its nodes' increments and e_i(s) the same
// interpolation of e at the anchors: eps_s = xi(s) + e_s - e_i(s). Its variance per slice is
// taken over kSteadyDraws draws of the process at every slice (exact transitions; fixed seed).
// Left out: the pairs' response to e_s - e_i(s) (the process's deviation from its interpolation
// between nodes 15 s apart, a few mm), which the correction would partly follow: conservative.
// Without pairs xi = e at the anchors and eps_s = e_s: f, as before.
// Where a semi-rigid iterate is kept (decision 045) the same response is taken through the
// semi-rigid stage's normal equations at that iterate (its nodes every bin_slices slices, its
// pairs at the solver's weights), window by window where its posterior is: one undamped
// Gauss-Newton step from any start answers the INS's error by -H_s^-1 (g(e) - g(0)), so the
// response does not depend on the rigid stage's result it started from.
constexpr int kSteadyDraws = 256;
constexpr std::uint64_t kSteadySeed = 42;

// Whether SLAM's result is the rigid stage's: the semi-rigid stage kept its start (p holds no
// correction) and the rigid stage moved the poses T off the INS's.
bool RigidResultKept(const Input& in,
                     const Param& p,
                     const std::vector<Pose>& T,
                     const SlamConfig& cfg) {
    if (cfg.rigid_iterations <= 0) return false;
    for (std::size_t k = 0; k < p.num_nodes(); ++k) {
        if (!(p.tc[k].isZero(0.0) && p.Rc[k] == Eigen::Matrix3d::Identity())) return false;
    }
    for (std::size_t s = 0; s < T.size(); ++s) {
        if ((T[s].translation() - in.T_ins[s].translation()).norm() > 1e-6) return true;
    }
    return false;
}

// Whether the semi-rigid stage kept an iterate: some node of p holds a correction.
bool SemiRigidIterateKept(const Param& p) {
    for (std::size_t k = 0; k < p.num_nodes(); ++k) {
        if (!(p.tc[k].isZero(0.0) && p.Rc[k] == Eigen::Matrix3d::Identity())) return true;
    }
    return false;
}

// The pose terms' inputs alone (no points), whose INS positions the draws move.
Input PoseTermsInput(const Input& in) {
    Input out;
    out.input_index = in.input_index;
    out.t_s = in.t_s;
    out.T_ins = in.T_ins;
    out.sigma = in.sigma;
    out.sigma_floor = in.sigma_floor;
    out.position_white_sigma = in.position_white_sigma;
    out.breaks = in.breaks;
    return out;
}

// The gradient of the pose terms of p at T, stacked per node.
Eigen::VectorXd PoseTermsGradient(const Input& in,
                                  const Param& p,
                                  const std::vector<Pose>& T,
                                  const SlamConfig& cfg) {
    const std::size_t n = p.num_nodes();
    Terms acc(n);
    AddPoseTerms(in, p, T, cfg, /*linearise=*/true, acc);
    Eigen::VectorXd g(static_cast<Eigen::Index>(6 * n));
    for (std::size_t k = 0; k < n; ++k) {
        g.segment<6>(static_cast<Eigen::Index>(6 * k)) = acc.sys.grad()[k];
    }
    return g;
}

// Draw d of the steady error at slices [s0, s1) (e[s - s0]): per axis sigma f, correlation
// time tau, exact transitions between the slices' times, stationary at s0.
void SteadyDraw(const Input& in,
                const Eigen::Vector3d& f,
                double tau,
                int d,
                std::size_t s0,
                std::size_t s1,
                std::vector<Eigen::Vector3d>& e) {
    std::mt19937_64 rng(kSteadySeed * 1000003ULL + static_cast<std::uint64_t>(d));
    std::normal_distribution<double> normal;
    e.resize(s1 - s0);
    for (std::size_t s = s0; s < s1; ++s) {
        const Eigen::Vector3d u(normal(rng), normal(rng), normal(rng));
        if (s == s0) {
            e[0] = f.cwiseProduct(u);
            continue;
        }
        const double a = std::exp(-std::abs(in.t_s[s] - in.t_s[s - 1]) / tau);
        e[s - s0] = a * e[s - s0 - 1] + std::sqrt(std::max(0.0, 1.0 - a * a)) * f.cwiseProduct(u);
    }
}

// A stage's normal equations at T (its parametrisation q), its pairs as the solver weighs them
// (all their information, no design effect), factorised. False when it fails.
bool FactoriseStage(const Input& in,
                    const Param& q,
                    const std::vector<Pose>& T,
                    const std::vector<Pair>& pairs,
                    const SlamConfig& cfg,
                    std::unique_ptr<reg::DampedSolver<6>>& ne,
                    std::unique_ptr<Terms>& total) {
    const std::size_t m = q.num_nodes();
    total = std::make_unique<Terms>(m);
    AddPoseTerms(in, q, T, cfg, /*linearise=*/true, *total);
    tbb::enumerable_thread_specific<Terms> accs([m] { return Terms(m); });
    AddPairTerms(in, q, T, pairs, cfg, /*linearise=*/true, accs);
    for (const Terms& acc : accs) total->sys.Merge(acc.sys);
    ne = std::make_unique<reg::DampedSolver<6>>(total->sys);
    Eigen::VectorXd delta;
    return ne->Solve(0.0, &delta);
}

// The slices a response is taken over: the draws span [s0, s1) (every anchor of the
// parametrisation's nodes and the slices stated lie in it), the variance is stated for
// [from, to).
struct SteadySpan {
    std::size_t s0 = 0, s1 = 0;
    std::size_t from = 0, to = 0;
};

// The draws per solve (the right-hand sides held at once).
constexpr int kSteadyBatch = 64;

// Per slice of span.from .. span.to, the variance (east, north, up) of the result's error from
// the INS's steady position error (above) through the normal equations of parametrisation q
// (the rigid stage's or the semi-rigid stage's) at T with `pairs` at the solver's weights;
// empty when they cannot be solved.
std::vector<Eigen::Vector3d> SteadyVariance(const Input& in,
                                            const Param& q,
                                            const std::vector<Pose>& T,
                                            const std::vector<Pair>& pairs,
                                            const SteadySpan& span,
                                            const SlamConfig& cfg) {
    const std::size_t m = q.num_nodes();
    std::unique_ptr<reg::DampedSolver<6>> ne;
    std::unique_ptr<Terms> total;
    if (m == 0 || !FactoriseStage(in, q, T, pairs, cfg, ne, total)) return {};
    const Eigen::Vector3d f = in.sigma_floor.tail<3>().cwiseMax(0.0);
    const double tau = std::max(cfg.ins_correlation_time_s, 1e-3);
    Input ins = PoseTermsInput(in);
    const Eigen::VectorXd g0 = PoseTermsGradient(ins, q, T, cfg);
    const std::size_t n = span.to - span.from;
    // The slice's translation from its node increment (rot, trans): trans + rot x lever, the
    // lever as NodeToSlice takes it.
    std::vector<Eigen::Vector3d> lever(n);
    for (std::size_t i = 0; i < n; ++i) {
        const std::size_t s = span.from + i;
        Eigen::Matrix3d R;
        Eigen::Vector3d t;
        SliceCorrection(q, s, &R, &t);
        lever[i] = T[s].translation() - q.pivot[s] - t;
    }
    std::vector<Eigen::Vector3d> var(n, Eigen::Vector3d::Zero());
    for (int b0 = 0; b0 < kSteadyDraws; b0 += kSteadyBatch) {
        const int nb = std::min(kSteadyBatch, kSteadyDraws - b0);
        Eigen::MatrixXd G(g0.size(), nb);
        std::vector<Eigen::Vector3d> ea(m * static_cast<std::size_t>(nb)), e;
        for (int d = 0; d < nb; ++d) {
            SteadyDraw(in, f, tau, b0 + d, span.s0, span.s1, e);
            for (std::size_t k = 0; k < m; ++k) {
                const auto a = static_cast<std::size_t>(q.anchor[k]);
                ea[static_cast<std::size_t>(d) * m + k] = e[a - span.s0];
                ins.T_ins[a].translation() = in.T_ins[a].translation() + e[a - span.s0];
            }
            G.col(d) = PoseTermsGradient(ins, q, T, cfg) - g0;
        }
        const Eigen::MatrixXd X = ne->SolveMany(G);
        if (X.size() == 0) return {};
        tbb::enumerable_thread_specific<std::vector<Eigen::Vector3d>> acc(
            [n] { return std::vector<Eigen::Vector3d>(n, Eigen::Vector3d::Zero()); });
        tbb::parallel_for(0, nb, [&](int d) {
            // The draw made again (the same seed): holding the batch's draws of every slice
            // would take 64 x 24 bytes a slice, 150 MB at 100 000 slices; a draw is cheap.
            std::vector<Eigen::Vector3d> ed;
            SteadyDraw(in, f, tau, b0 + d, span.s0, span.s1, ed);
            std::vector<Eigen::Vector3d>& v = acc.local();
            const auto o = static_cast<std::size_t>(d) * m;
            for (std::size_t i = 0; i < n; ++i) {
                const std::size_t s = span.from + i;
                const auto k0 = static_cast<std::size_t>(q.k0[s]);
                const auto k1 = static_cast<std::size_t>(q.k1[s]);
                const double w = q.alpha[s];
                const Vector6d x =
                    (1.0 - w) * X.col(d).segment<6>(static_cast<Eigen::Index>(6 * k0)) +
                    w * X.col(d).segment<6>(static_cast<Eigen::Index>(6 * k1));
                // xi = -x = -H^-1 (g(e) - g(0)); the slice's translation as NodeToSlice makes it.
                const Eigen::Vector3d moved = -(x.tail<3>() + x.head<3>().cross(lever[i]));
                const Eigen::Vector3d eps =
                    moved + ed[s - span.s0] - ((1.0 - w) * ea[o + k0] + w * ea[o + k1]);
                v[i] += eps.cwiseAbs2();
            }
        });
        for (const auto& v : acc) {
            for (std::size_t i = 0; i < n; ++i) var[i] += v[i];
        }
    }
    for (Eigen::Vector3d& v : var) v /= static_cast<double>(kSteadyDraws);
    return var;
}

// Per slice, the variance of the rigid result's error from the INS's steady position error:
// the rigid stage's parametrisation of the kept poses (decision 042).
std::vector<Eigen::Vector3d> RigidSteadyVariance(const Input& in,
                                                 const std::vector<Pose>& T,
                                                 const std::vector<Block>& blocks,
                                                 const std::vector<Pair>& pairs,
                                                 const SlamConfig& cfg) {
    const Param pr = RigidParam(in, T, blocks, cfg);
    const SteadySpan all{0, in.num_slices(), 0, in.num_slices()};
    return SteadyVariance(in, pr, T, pairs, all, cfg);
}

// Per slice, the variance of the semi-rigid result's error from the INS's steady position
// error (decision 045): the semi-rigid stage's own normal equations at the kept iterate p, its
// pairs at the solver's weights, window by window as its posterior (each window's terms, its
// core's slices kept); empty when a window cannot be solved.
std::vector<Eigen::Vector3d> SemiRigidSteadyVariance(const Input& in,
                                                     const Param& p,
                                                     const std::vector<Pose>& T,
                                                     const std::vector<Pair>& pairs,
                                                     const std::vector<NodeWindow>& windows,
                                                     const SlamConfig& cfg) {
    const std::size_t ns = in.num_slices();
    const std::size_t n = p.num_nodes();
    if (windows.size() <= 1) return SteadyVariance(in, p, T, pairs, {0, ns, 0, ns}, cfg);
    // A slice no window's core states (a core whose last slices reach a node past its window:
    // no overlap) keeps the steady error whole.
    const Eigen::Vector3d f = in.sigma_floor.tail<3>().cwiseMax(0.0);
    std::vector<Eigen::Vector3d> var(ns, f.cwiseAbs2());
    const auto anchor = [&](std::size_t k) {
        return k < n ? static_cast<std::size_t>(p.anchor[k]) : ns;
    };
    for (const NodeWindow& w : windows) {
        std::vector<Pair> inside;
        for (const Pair& pr : pairs) {
            if (PairInWindow(p, pr, w.first, w.last)) inside.push_back(pr);
        }
        const std::size_t s1 = w.last < n ? anchor(w.last) : ns;
        const std::size_t inside_last = w.last < n ? anchor(w.last - 1) + 1 : ns;
        const SteadySpan span{
            anchor(w.first), s1, anchor(w.core_first), std::min(anchor(w.core_last), inside_last)};
        if (span.to <= span.from) continue;
        const std::vector<Eigen::Vector3d> v =
            SteadyVariance(in, WindowParam(p, w.first, w.last), T, inside, span, cfg);
        if (v.empty()) return {};
        std::copy(v.begin(), v.end(), var.begin() + static_cast<std::ptrdiff_t>(span.from));
    }
    return var;
}

// The slice's 1-sigma roll, pitch, yaw and position: the interpolated perturbation of its two
// nodes (node blocks Ckk, cross blocks Ckn of consecutive nodes), with the INS's steady error
// added when posterior_reference_sigma: its position part as `steady_var` states it (the rigid
// result's response, RigidSteadyVariance), or whole when that is null.
Vector6d SliceSigma(const Input& in,
                    const Param& p,
                    const std::vector<Pose>& T,
                    const std::vector<Matrix6d>& Ckk,
                    const std::vector<Matrix6d>& Ckn,
                    const SlamConfig& cfg,
                    std::size_t s,
                    const Eigen::Vector3d* steady_var) {
    const auto k0 = static_cast<std::size_t>(p.k0[s]);
    Matrix6d C;
    if (p.alpha[s] == 0.0) {
        const Matrix6d A = NodeToSlice(p, T[s], s, 1.0);
        C = A * Ckk[k0] * A.transpose();
    } else {
        const auto k1 = static_cast<std::size_t>(p.k1[s]);
        const Matrix6d A = NodeToSlice(p, T[s], s, 1.0 - p.alpha[s]);
        const Matrix6d B = NodeToSlice(p, T[s], s, p.alpha[s]);
        // k1 = k0 + 1 (consecutive nodes): the cross block is C_{k0,k1}.
        const Matrix6d X = k1 == k0 + 1 ? Ckn[k0] : Matrix6d::Zero();
        const Matrix6d AXBt = A * X * B.transpose();
        C = A * Ckk[k0] * A.transpose() + B * Ckk[k1] * B.transpose() + AXBt + AXBt.transpose();
    }
    if (cfg.posterior_reference_sigma) {
        // SLAM is tied to the INS: its steady error (the survey's smallest sigma f, what it
        // holds with GNSS), whole (the result follows the INS: common to the passes it aligns)
        // or as the rigid result carries it (steady_var). The attitude's steady part whole.
        // The white noise of each INS output (PositionWhiteNoise) stays in every ping too.
        // The slow error where the data state it larger than the INS reports (decision 027):
        // its excess over f whole.
        for (int c = 0; c < 3; ++c) {
            const double f = in.sigma_floor(3 + c);
            const double stated = c < 2 ? std::max(f, cfg.reference_horizontal_sigma_m) : f;
            const double steady2 = steady_var != nullptr
                                       ? (*steady_var)(c) + stated * stated - f * f
                                       : stated * stated;
            C(c, c) += in.sigma_floor(c) * in.sigma_floor(c);
            C(3 + c, 3 + c) += steady2 + in.position_white_sigma(c) * in.position_white_sigma(c);
        }
    }
    Vector6d sig;
    sig.head<3>() = RollPitchYawSigma(T[s].linear(), C.topLeftCorner<3, 3>());
    sig.tail<3>() = C.bottomRightCorner<3, 3>().diagonal().cwiseMax(0.0).cwiseSqrt();
    return sig;
}

// The marginal blocks Ckk, Ckn (scaled formal part plus the cluster-robust part) window by
// window (SlamPosterior::windows): each window's normal equations from the terms within it
// (WindowParam), its cores' blocks kept. Leaving out the terms that reach outside a window is
// conservative: the window's information is then at most the Schur complement of the whole
// system's onto the window (a Schur complement of the left-out terms' positive semidefinite
// information adds to it), so its covariance at least the whole solve's. Fills the
// observation counts, the variance factor and the timings of `post`; false with
// post.message set when a window fails.
bool WindowedMarginals(const Input& in,
                       const Param& p,
                       const std::vector<Pose>& T,
                       const std::vector<Pair>& pairs,
                       const std::vector<NodeWindow>& windows,
                       PairInformation pair_info,
                       const SlamConfig& cfg,
                       SlamPosterior& post,
                       std::vector<Matrix6d>& Ckk,
                       std::vector<Matrix6d>& Ckn) {
    const std::size_t n = p.num_nodes();
    const double scale = CovarianceScale(n, pairs.size(), CostAt(in, p, pairs, cfg), cfg, post);
    if (!(std::isfinite(scale) && scale > 0)) {
        post.message = "no redundancy (" + std::to_string(post.observations) +
                       " observations for " + std::to_string(post.unknowns) + " unknowns)";
        return false;
    }
    Ckk.assign(n, Matrix6d::Zero());
    Ckn.assign(n, Matrix6d::Zero());
    std::vector<double> formal_h;
    post.windows = windows.size();
    for (const NodeWindow& w : windows) {
        auto t0 = Clock::now();
        const Param wp = WindowParam(p, w.first, w.last);
        std::vector<Pair> inside;
        for (const Pair& pr : pairs) {
            if (PairInWindow(p, pr, w.first, w.last)) inside.push_back(pr);
        }
        const Clusters clusters = ClusterPairs(inside);
        const Terms terms =
            PosteriorTerms(in, wp, T, clusters, post.residual_correlation, pair_info, cfg);
        reg::DampedSolver<6> ne(terms.sys);
        post.largest_factor_nonzeros = std::max(post.largest_factor_nonzeros, ne.factor_nonzeros());
        post.build_s += Seconds(t0);
        t0 = Clock::now();
        Eigen::VectorXd delta;
        if (!ne.Solve(0.0, &delta)) {
            post.message = "CHOLMOD could not factorise the undamped normal equations of a window";
            return false;
        }
        post.factor_s += Seconds(t0);
        t0 = Clock::now();
        std::vector<std::size_t> which;
        for (std::size_t k = w.core_first; k < w.core_last; ++k) which.push_back(k - w.first);
        std::vector<Matrix6d> wkk, wkn;
        if (!ne.InverseBlocks(which, cfg.posterior_batch_nodes, &wkk, &wkn)) {
            post.message = "the marginal covariances of a window could not be solved";
            return false;
        }
        std::vector<Matrix6d> rkk(w.last - w.first, Matrix6d::Zero()), rkn = rkk;
        std::size_t num_clusters = 0;
        if (cfg.posterior_cluster_robust && !AddClusterRobust(in,
                                                              wp,
                                                              T,
                                                              clusters,
                                                              post.residual_correlation,
                                                              cfg,
                                                              pair_info,
                                                              ne,
                                                              rkk,
                                                              rkn,
                                                              &num_clusters)) {
            post.message = "the cluster-robust covariance of a window could not be solved";
            return false;
        }
        post.clusters += num_clusters;
        for (std::size_t i = 0; i < which.size(); ++i) {
            const std::size_t k = w.core_first + i;
            const Matrix6d F = wkk[i];
            formal_h.push_back(std::sqrt(std::max(0.0, 0.5 * (F(3, 3) + F(4, 4)))));
            Ckk[k] = scale * F + rkk[which[i]];
            Ckn[k] = scale * wkn[i] + rkn[which[i]];
        }
        post.nodes_solved += which.size();
        post.marginals_s += Seconds(t0);
    }
    std::nth_element(formal_h.begin(),
                     formal_h.begin() + static_cast<std::ptrdiff_t>(formal_h.size() / 2),
                     formal_h.end());
    post.formal_horizontal_median_m = formal_h[formal_h.size() / 2];
    return true;
}

// post.slice_sigma from the node blocks, the steady position error as the kept result carries
// it: the rigid stage's response where the result is the rigid stage's (RigidResultKept), the
// semi-rigid stage's where its iterate is kept (SemiRigidIterateKept), else whole (the result
// is the INS's); sets computed.
void FillSliceSigma(const Input& in,
                    const Param& p,
                    const std::vector<Pose>& T,
                    const std::vector<Block>& blocks,
                    const std::vector<Pair>& pairs,
                    const std::vector<NodeWindow>& windows,
                    const std::vector<Matrix6d>& Ckk,
                    const std::vector<Matrix6d>& Ckn,
                    const SlamConfig& cfg,
                    SlamPosterior& post) {
    const auto t0 = Clock::now();
    std::vector<Eigen::Vector3d> steady;
    if (!cfg.posterior_reference_sigma) {
        post.steady_model = "none";
    } else if (RigidResultKept(in, p, T, cfg)) {
        steady = RigidSteadyVariance(in, T, blocks, pairs, cfg);
        post.steady_model = steady.empty() ? "whole (the rigid response failed)" : "rigid_response";
    } else if (SemiRigidIterateKept(p)) {
        steady = SemiRigidSteadyVariance(in, p, T, pairs, windows, cfg);
        post.steady_model =
            steady.empty() ? "whole (the semi-rigid response failed)" : "semi_rigid_response";
    } else {
        post.steady_model = "whole";
    }
    post.steady_s = Seconds(t0);
    post.slice_sigma.resize(in.num_slices());
    for (std::size_t s = 0; s < in.num_slices(); ++s) {
        post.slice_sigma[s] =
            SliceSigma(in, p, T, Ckk, Ckn, cfg, s, steady.empty() ? nullptr : &steady[s]);
    }
    if (!steady.empty()) {
        std::vector<double> up(steady.size());
        for (std::size_t s = 0; s < steady.size(); ++s) up[s] = std::sqrt(steady[s](2));
        std::nth_element(
            up.begin(), up.begin() + static_cast<std::ptrdiff_t>(up.size() / 2), up.end());
        post.steady_up_median_m = up[up.size() / 2];
    }
    post.computed = true;
}

}  // namespace

void ComputePosterior(const Input& in,
                      const Param& p,
                      std::vector<Block>& blocks,
                      const std::vector<std::uint32_t>& slice_block,
                      const SlamConfig& cfg,
                      SlamResult& res) {
    const auto t_start = Clock::now();
    SlamPosterior& post = res.posterior;
    post = SlamPosterior{};
    if (cfg.posterior_reference_sigma) {
        post.ins_white_noise_m = in.position_white_sigma;
        post.reference_horizontal_sigma_m =
            std::max({in.sigma_floor(3), in.sigma_floor(4), cfg.reference_horizontal_sigma_m});
    }
    const auto fail = [&](std::string message) {
        post.message = std::move(message);
        post.total_s = Seconds(t_start);
    };
    const std::size_t n = p.num_nodes();
    const std::vector<Pose> T = SlicePoses(p);

    auto t0 = Clock::now();
    const std::vector<Pair> pairs = PairsAtKeptIterate(in, T, blocks, slice_block, cfg, res);
    post.search_s = Seconds(t0);
    post.num_pairs = pairs.size();

    t0 = Clock::now();
    // GICP's along-surface sigma (gicp_tangent_sigma_m) is a loose bound that lets the solver
    // slide a pass along a surface, not a measurement: a pair's offset along the surface is
    // where the other pass's nearest sounding happens to lie (docs/decisions/002), alike for
    // every pair of an overlap. Read as independent information it states the along-track
    // position of a pass in a GNSS outage to a few cm from 10^4 pairs along a featureless bench
    // (docs/decisions/012). So a pair informs the posterior along its normal alone, unless
    // posterior_tangent_information.
    const PairInformation pair_info = cfg.posterior_tangent_information
                                          ? PairInformation::kAsConfigured
                                          : PairInformation::kNormalOnly;
    // The pairs of one cluster (two rigid sections) share the errors of both passes' surfaces
    // (the INS attitude, the boresight and sound speed residuals): their information is
    // scaled by the design effect with the residuals' intra-cluster correlation (decision 012).
    const Clusters clusters = ClusterPairs(pairs);
    post.residual_correlation = ResidualCorrelation(in, T, clusters, cfg);
    const std::vector<NodeWindow> windows =
        MakeWindows(in, p, cfg.semi_rigid_window_s, cfg.semi_rigid_window_overlap_s, /*shift=*/0.0);
    std::vector<Matrix6d> Ckk, Ckn;
    if (windows.size() > 1) {
        post.build_s = Seconds(t0);
        if (!WindowedMarginals(in, p, T, pairs, windows, pair_info, cfg, post, Ckk, Ckn)) {
            return fail(post.message);
        }
        FillSliceSigma(in, p, T, blocks, pairs, windows, Ckk, Ckn, cfg, post);
        post.total_s = Seconds(t_start);
        return;
    }
    const Terms total =
        PosteriorTerms(in, p, T, clusters, post.residual_correlation, pair_info, cfg);
    reg::DampedSolver<6> ne(total.sys);
    post.largest_factor_nonzeros = ne.factor_nonzeros();
    post.build_s = Seconds(t0);

    const double scale = CovarianceScale(n, pairs.size(), total.cost, cfg, post);
    if (!(std::isfinite(scale) && scale > 0)) {
        return fail("no redundancy (" + std::to_string(post.observations) + " observations for " +
                    std::to_string(post.unknowns) + " unknowns)");
    }

    t0 = Clock::now();
    Eigen::VectorXd delta;
    if (!ne.Solve(0.0, &delta)) {
        return fail("CHOLMOD could not factorise the undamped normal equations");
    }
    post.factor_s = Seconds(t0);

    t0 = Clock::now();
    std::vector<std::size_t> which(n);
    for (std::size_t k = 0; k < n; ++k) which[k] = k;
    if (!ne.InverseBlocks(which, cfg.posterior_batch_nodes, &Ckk, &Ckn)) {
        return fail("the marginal covariances could not be solved");
    }
    post.nodes_solved = n;
    for (std::size_t k = 0; k < n; ++k) {
        Ckk[k] *= scale;
        Ckn[k] *= scale;
    }
    // Formal horizontal sigma at the nodes' anchor slices, for the record.
    post.formal_horizontal_median_m = FormalHorizontalMedian(Ckk, scale);
    if (cfg.posterior_cluster_robust && !AddClusterRobust(in,
                                                          p,
                                                          T,
                                                          clusters,
                                                          post.residual_correlation,
                                                          cfg,
                                                          pair_info,
                                                          ne,
                                                          Ckk,
                                                          Ckn,
                                                          &post.clusters)) {
        return fail("the cluster-robust covariance could not be solved");
    }
    post.marginals_s = Seconds(t0);

    FillSliceSigma(in, p, T, blocks, pairs, windows, Ckk, Ckn, cfg, post);
    post.total_s = Seconds(t_start);
}

}  // namespace pitmap::proc::slam::detail
