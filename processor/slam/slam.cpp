// SPDX-License-Identifier: MIT
#include "processor/slam/slam.hpp"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <Eigen/Cholesky>
#include <Eigen/CholmodSupport>
#include <Eigen/Eigenvalues>
#include <Eigen/SparseCore>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <numeric>
#include <optional>
#include <unordered_map>

#include <nanoflann.hpp>

namespace pitmap::proc::slam {

namespace {

using Clock = std::chrono::steady_clock;

double Seconds(Clock::time_point a) {
    return std::chrono::duration<double>(Clock::now() - a).count();
}

// ---- input, sorted by time ------------------------------------------------------------------

struct Input {
    std::vector<std::size_t> input_index;  // sorted slice -> input slice
    std::vector<double> t_s;
    std::vector<Pose> T_ins;      // INS poses (measurements)
    std::vector<Vector6d> sigma;  // effective INS 1-sigma (see ins_sigma_recovery_time_s)
    Vector6d sigma_floor = Vector6d::Zero();  // smallest sigma of the survey, per component
    std::vector<std::size_t> offset;          // first point of each slice in `points`
    std::vector<Eigen::Vector3f> points;      // vehicle frame, finite only
    // Slices where GNSS returns after an outage: the INS pulls its drift back within seconds
    // there, so sections and bins start there and are short after them (the correction stays
    // continuous; its rate changes).
    std::vector<std::size_t> breaks;
    std::size_t num_slices() const { return t_s.size(); }
    bool IsBreak(std::size_t s) const {
        return std::binary_search(breaks.begin(), breaks.end(), s);
    }
};

// GNSS recoveries: the reported horizontal 1-sigma falls below half its largest value of the
// previous kBreakWindowS, from above min_sigma_m (one break per kBreakWindowS at most).
constexpr double kBreakWindowS = 2.0;
constexpr double kBreakFirstSectionS = 1.0;  // first section after a recovery
std::vector<std::size_t> FindBreaks(const std::vector<double>& t_s,
                                    const std::vector<Vector6d>& reported,
                                    double min_sigma_m) {
    std::vector<std::size_t> breaks;
    std::size_t w0 = 0;
    for (std::size_t s = 1; s < t_s.size(); ++s) {
        while (t_s[w0] < t_s[s] - kBreakWindowS) ++w0;
        double peak = 0;
        for (std::size_t k = w0; k < s; ++k) {
            peak = std::max(peak, std::max(reported[k](3), reported[k](4)));
        }
        const double now = std::max(reported[s](3), reported[s](4));
        const bool recent = !breaks.empty() && t_s[breaks.back()] > t_s[s] - kBreakWindowS;
        if (peak > min_sigma_m && now < 0.5 * peak && !recent) breaks.push_back(s);
    }
    return breaks;
}

bool FinitePose(const Pose& T) {
    return T.matrix().allFinite();
}

// ---- parametrisation: node corrections applied to per-slice base poses ----------------------
// Slice pose: R = Rc * R_base, t = Rc (t_base - pivot) + pivot + tc, with (Rc, tc) the node
// correction (interpolated between two nodes with weight alpha in a bin).

struct Param {
    std::vector<Pose> base;
    std::vector<Eigen::Vector3d> pivot;
    std::vector<int> k0, k1;
    std::vector<double> alpha;
    std::vector<int> anchor;  // node -> slice whose pose depends on that node alone
    std::vector<Eigen::Matrix3d> Rc;
    std::vector<Eigen::Vector3d> tc;
    std::size_t num_nodes() const { return anchor.size(); }
};

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

// ---- k-d tree blocks ------------------------------------------------------------------------

struct BlockCloud {
    const Eigen::Vector3f* pts = nullptr;
    std::size_t n = 0;
    std::size_t kdtree_get_point_count() const { return n; }
    float kdtree_get_pt(std::size_t i, std::size_t d) const { return pts[i][static_cast<int>(d)]; }
    template <class B>
    bool kdtree_get_bbox(B& /*bb*/) const {
        return false;
    }
};
using KdTree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, BlockCloud>,
                                                   BlockCloud,
                                                   3,
                                                   std::size_t>;

struct Block {
    std::size_t s0 = 0, s1 = 0;                    // slices [s0, s1)
    std::size_t p0 = 0, p1 = 0;                    // points [p0, p1)
    double t0 = 0, t1 = 0;                         // time span
    Eigen::Vector3f lo = Eigen::Vector3f::Zero();  // bounding box of the world points
    Eigen::Vector3f hi = Eigen::Vector3f::Zero();
    BlockCloud cloud;
    std::unique_ptr<KdTree> tree;
};

std::vector<Block> MakeBlocks(const Input& in, double length_s) {
    std::vector<Block> blocks;
    std::size_t s = 0;
    double t_break = -std::numeric_limits<double>::infinity();
    while (s < in.num_slices()) {
        Block b;
        if (in.IsBreak(s)) t_break = in.t_s[s];
        b.s0 = s++;
        // After a GNSS recovery the INS error falls within seconds: sections of 1, 1, 2, 4, 8 s
        // there (doubling up to length_s), so that the rigid stage can follow the fall.
        const double since = in.t_s[b.s0] - t_break;
        const double len =
            since < length_s ? std::clamp(since, kBreakFirstSectionS, length_s) : length_s;
        while (s < in.num_slices() && in.t_s[s] < in.t_s[b.s0] + len && !in.IsBreak(s)) ++s;
        b.s1 = s;
        b.p0 = in.offset[b.s0];
        b.p1 = in.offset[b.s1];
        b.t0 = in.t_s[b.s0];
        b.t1 = in.t_s[b.s1 - 1];
        blocks.push_back(std::move(b));
    }
    return blocks;
}

void BuildTrees(std::vector<Block>& blocks, const std::vector<Eigen::Vector3f>& pw) {
    tbb::parallel_for(std::size_t{0}, blocks.size(), [&](std::size_t i) {
        Block& b = blocks[i];
        b.cloud.pts = pw.data() + b.p0;
        b.cloud.n = b.p1 - b.p0;
        b.lo.setConstant(std::numeric_limits<float>::max());
        b.hi.setConstant(std::numeric_limits<float>::lowest());
        for (std::size_t k = b.p0; k < b.p1; ++k) {
            b.lo = b.lo.cwiseMin(pw[k]);
            b.hi = b.hi.cwiseMax(pw[k]);
        }
        b.tree.reset();
        if (b.cloud.n > 0) {
            b.tree =
                std::make_unique<KdTree>(3, b.cloud, nanoflann::KDTreeSingleIndexAdaptorParams(16));
        }
    });
}

struct Pair {
    std::uint32_t slice_a = 0, slice_b = 0;
    std::size_t point_a = 0, point_b = 0;  // global point indices
    std::uint32_t block_a = 0, block_b = 0;
    Eigen::Vector3f normal_a = Eigen::Vector3f::Zero();
    Eigen::Vector3f normal_b = Eigen::Vector3f::Zero();
};

// Closest point of pw[q] among blocks entirely at least t_d away in time, within d_max.
// Also the pair score of the current poses: sqrt(mean(min(d, score_m)^2)) over the query
// points that have a partner block (time and bounding box), d the distance to the closest
// point (score_m when none is within the search distance); score_m <= the search distance.
std::vector<Pair> FindPairs(const Input& in,
                            const std::vector<Block>& blocks,
                            const std::vector<std::uint32_t>& slice_block,
                            const std::vector<Eigen::Vector3f>& pw,
                            const SlamConfig& cfg,
                            double score_m,
                            double* score) {
    const float dmax = static_cast<float>(cfg.max_pair_distance_m);
    const float dmax2 = dmax * dmax;
    const double score2 = score_m * score_m;
    std::vector<double> slice_sum(in.num_slices(), 0.0);
    std::vector<std::uint32_t> slice_count(in.num_slices(), 0);
    const double td = cfg.min_time_separation_s;
    const auto stride = static_cast<std::size_t>(cfg.query_stride);
    // Blocks per horizontal cell (cells of at least 2 dmax): a block is listed in every cell
    // its points come within dmax of, so that a query visits only the trees that can hold its
    // partner, not every tree whose bounding box it touches.
    const float cell = std::max(2.0f * dmax, 2.0f);
    auto cell_key = [cell](float x, float y) {
        const auto ix = static_cast<std::int64_t>(std::floor(x / cell)) + (1 << 30);
        const auto iy = static_cast<std::int64_t>(std::floor(y / cell)) + (1 << 30);
        return (static_cast<std::uint64_t>(ix) << 32) | static_cast<std::uint64_t>(iy);
    };
    std::vector<std::vector<std::uint64_t>> block_cells(blocks.size());
    tbb::parallel_for(std::size_t{0}, blocks.size(), [&](std::size_t bi) {
        const Block& b = blocks[bi];
        auto& keys = block_cells[bi];
        for (std::size_t k = b.p0; k < b.p1; ++k) {
            const Eigen::Vector3f& p = pw[k];
            for (const float dx : {-dmax, dmax}) {
                for (const float dy : {-dmax, dmax}) {
                    const std::uint64_t key = cell_key(p.x() + dx, p.y() + dy);
                    if (keys.empty() || keys.back() != key) keys.push_back(key);
                }
            }
        }
        std::sort(keys.begin(), keys.end());
        keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
    });
    std::unordered_map<std::uint64_t, std::vector<std::uint32_t>> cell_blocks;
    for (std::uint32_t bi = 0; bi < blocks.size(); ++bi) {
        for (const std::uint64_t key : block_cells[bi]) cell_blocks[key].push_back(bi);
    }
    const std::vector<std::uint32_t> no_blocks;
    tbb::enumerable_thread_specific<std::vector<Pair>> local;
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, in.num_slices(), 64),
        [&](const tbb::blocked_range<std::size_t>& range) {
            auto& out = local.local();
            for (std::size_t s = range.begin(); s != range.end(); ++s) {
                const double t = in.t_s[s];
                for (std::size_t q = in.offset[s] + s % stride; q < in.offset[s + 1]; q += stride) {
                    const Eigen::Vector3f& p = pw[q];
                    float best = dmax2;
                    std::size_t best_idx = 0;
                    std::uint32_t best_block = 0;
                    bool found = false, candidate = false;
                    // Score bookkeeping: does any time-separated block's box come within score_m?
                    const float sm = static_cast<float>(score_m);
                    for (const Block& b : blocks) {
                        if (!b.tree || !(b.t1 <= t - td || b.t0 >= t + td)) continue;
                        if (!((p.array() < b.lo.array() - sm).any() ||
                              (p.array() > b.hi.array() + sm).any())) {
                            candidate = true;
                            break;
                        }
                    }
                    const auto cb = cell_blocks.find(cell_key(p.x(), p.y()));
                    for (const std::uint32_t bi :
                         cb == cell_blocks.end() ? no_blocks : cb->second) {
                        const Block& b = blocks[bi];
                        if (!b.tree || !(b.t1 <= t - td || b.t0 >= t + td)) continue;
                        if ((p.array() < b.lo.array() - dmax).any() ||
                            (p.array() > b.hi.array() + dmax).any()) {
                            continue;
                        }
                        std::size_t idx = 0;
                        float d2 = 0;
                        if (b.tree->knnSearch(p.data(), 1, &idx, &d2) == 1 && d2 < best) {
                            best = d2;
                            best_idx = b.p0 + idx;
                            best_block = bi;
                            found = true;
                        }
                    }
                    if (candidate) {
                        slice_sum[s] +=
                            found ? std::min(static_cast<double>(best), score2) : score2;
                        ++slice_count[s];
                    }
                    if (!found) continue;
                    Pair pr;
                    pr.slice_a = static_cast<std::uint32_t>(s);
                    pr.point_a = q;
                    pr.block_a = slice_block[s];
                    pr.point_b = best_idx;
                    pr.block_b = best_block;
                    const auto it = std::upper_bound(in.offset.begin(), in.offset.end(), best_idx);
                    pr.slice_b = static_cast<std::uint32_t>(it - in.offset.begin() - 1);
                    out.push_back(pr);
                }
            }
        });
    double sum = 0, count = 0;
    for (std::size_t s = 0; s < in.num_slices(); ++s) {
        sum += slice_sum[s];
        count += slice_count[s];
    }
    *score = count > 0 ? std::sqrt(sum / count) : 0.0;
    std::vector<Pair> pairs;
    for (auto& v : local) pairs.insert(pairs.end(), v.begin(), v.end());
    // Thread order is arbitrary; sort so that the sums below see the same order every run.
    std::sort(pairs.begin(), pairs.end(), [](const Pair& a, const Pair& b) {
        return a.point_a < b.point_a;
    });
    return pairs;
}

// Unit normal of the points around pw[k] in its block (smallest eigenvector of the local
// covariance); zero if fewer than 3 neighbours.
Eigen::Vector3f LocalNormal(const Block& b,
                            const std::vector<Eigen::Vector3f>& pw,
                            std::size_t k,
                            int num_neighbours) {
    std::vector<std::size_t> idx(static_cast<std::size_t>(num_neighbours));
    std::vector<float> d2(idx.size());
    const std::size_t n = b.tree->knnSearch(pw[k].data(), idx.size(), idx.data(), d2.data());
    if (n < 3) return Eigen::Vector3f::Zero();
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < n; ++i) mean += pw[b.p0 + idx[i]].cast<double>();
    mean /= static_cast<double>(n);
    Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
    for (std::size_t i = 0; i < n; ++i) {
        const Eigen::Vector3d d = pw[b.p0 + idx[i]].cast<double>() - mean;
        C += d * d.transpose();
    }
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(C);
    Eigen::Vector3d nrm = es.eigenvectors().col(0);
    if (nrm.z() < 0) nrm = -nrm;
    return nrm.cast<float>();
}

// ---- normal equations -----------------------------------------------------------------------

struct Accum {
    std::vector<Matrix6d> diag;
    std::vector<Vector6d> grad;
    std::unordered_map<std::uint64_t, Matrix6d> off;  // key i * n + j, i < j
    double cost = 0;
    double sq_dist = 0;
    explicit Accum(std::size_t n) : diag(n, Matrix6d::Zero()), grad(n, Vector6d::Zero()) {}
};

// Adds J^T W J and J^T W r for a residual that depends on up to 4 nodes.
template <int M>
void AddTerm(Accum& acc,
             std::size_t n,
             const int* nodes,
             const Eigen::Matrix<double, M, 6>* J,
             int count,
             const Eigen::Matrix<double, M, M>& W,
             const Eigen::Matrix<double, M, 1>& r) {
    for (int i = 0; i < count; ++i) {
        const Eigen::Matrix<double, 6, M> JtW = J[i].transpose() * W;
        acc.grad[static_cast<std::size_t>(nodes[i])] += JtW * r;
        for (int j = 0; j < count; ++j) {
            if (nodes[i] == nodes[j]) {
                acc.diag[static_cast<std::size_t>(nodes[i])] += JtW * J[j];
            } else if (nodes[i] < nodes[j]) {
                const std::uint64_t key =
                    static_cast<std::uint64_t>(nodes[i]) * n + static_cast<std::uint64_t>(nodes[j]);
                auto it = acc.off.find(key);
                if (it == acc.off.end()) it = acc.off.emplace(key, Matrix6d::Zero()).first;
                it->second += JtW * J[j];
            }
        }
    }
}

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

// Relative-motion and absolute terms (no pairs).
// With linearise false only acc.cost is accumulated (the step acceptance test).
void AddPoseTerms(const Input& in,
                  const Param& p,
                  const std::vector<Pose>& T,
                  const SlamConfig& cfg,
                  bool linearise,
                  Accum& acc) {
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
        AddTerm<6>(acc, n, nodes, J, 2, W, r);
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
            const Matrix36d J[3] = {-B[0] / d0, -(1.0 / d1 + 1.0 / d0) * B[1], B[2] / d1};
            AddTerm<3>(acc, n, nodes, J, 3, W, r);
        }
    }
    const bool abs_any = cfg.absolute_position_terms || cfg.absolute_attitude_terms;
    for (std::size_t k = 0; k < n; ++k) {
        const auto i = static_cast<std::size_t>(p.anchor[k]);
        Matrix6d Ja;
        const Vector6d r = AbsolutePoseResidual(T[i], in.T_ins[i], &Ja);
        Vector6d info = Vector6d::Zero();
        if (abs_any) {
            const Vector6d sig = SigmaVector(in.sigma[i], cfg.absolute_sigma_scale);
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
        AddTerm<6>(acc, n, nodes, J, 1, W, r);
    }
}

// Pair terms; with linearise false only the robust cost (and sq_dist) are accumulated.
void AddPairTerms(const Input& in,
                  const Param& p,
                  const std::vector<Pose>& T,
                  const std::vector<Pair>& pairs,
                  const SlamConfig& cfg,
                  bool linearise,
                  tbb::enumerable_thread_specific<Accum>& accs) {
    const std::size_t n = p.num_nodes();
    const double s2 = cfg.point_sigma_m * cfg.point_sigma_m;
    const double t2 = cfg.gicp_tangent_sigma_m * cfg.gicp_tangent_sigma_m;
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, pairs.size(), 1024),
        [&](const tbb::blocked_range<std::size_t>& range) {
            Accum& acc = accs.local();
            for (std::size_t k = range.begin(); k != range.end(); ++k) {
                const Pair& pr = pairs[k];
                const std::size_t a = pr.slice_a, b = pr.slice_b;
                const Eigen::Vector3d xa = in.points[pr.point_a].cast<double>();
                const Eigen::Vector3d xb = in.points[pr.point_b].cast<double>();
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
                if (cfg.correspondence == CorrespondenceType::kPointToPlane) {
                    const Eigen::Vector3d nrm = pr.normal_b.cast<double>();
                    Eigen::Matrix<double, 1, 1> r;
                    r(0) = nrm.dot(r3);
                    const double sw = std::abs(r(0)) / cfg.point_sigma_m;
                    acc.cost += RobustCost(cfg.robust_kernel, sw, cfg.robust_width);
                    if (!linearise) continue;
                    Eigen::Matrix<double, 1, 1> W;
                    W(0) = RobustWeight(cfg.robust_kernel, sw, cfg.robust_width) / s2;
                    Matrix16d J[4];
                    for (int i = 0; i < count; ++i) {
                        const bool is_a = i < na;
                        const std::size_t s = is_a ? a : b;
                        J[i] = nrm.transpose() * (is_a ? Ja : Jb) * NodeToSlice(p, T[s], s, w[i]);
                    }
                    AddTerm<1>(acc, n, nodes, J, count, W, r);
                } else {
                    Eigen::Matrix3d info;
                    if (cfg.correspondence == CorrespondenceType::kGicp) {
                        const Eigen::Vector3d na3 = pr.normal_a.cast<double>();
                        const Eigen::Vector3d nb3 = pr.normal_b.cast<double>();
                        const Eigen::Matrix3d C =
                            2.0 * t2 * Eigen::Matrix3d::Identity() +
                            (s2 - t2) * (na3 * na3.transpose() + nb3 * nb3.transpose());
                        info = C.inverse();
                    } else {
                        info = Eigen::Matrix3d::Identity() / s2;
                    }
                    const double m2 = r3.dot(info * r3);
                    const double sw = std::sqrt(m2);
                    acc.cost += RobustCost(cfg.robust_kernel, sw, cfg.robust_width);
                    if (!linearise) continue;
                    const Eigen::Matrix3d W =
                        RobustWeight(cfg.robust_kernel, sw, cfg.robust_width) * info;
                    Matrix36d J[4];
                    for (int i = 0; i < count; ++i) {
                        const bool is_a = i < na;
                        const std::size_t s = is_a ? a : b;
                        J[i] = (is_a ? Ja : Jb) * NodeToSlice(p, T[s], s, w[i]);
                    }
                    AddTerm<3>(acc, n, nodes, J, count, W, r3);
                }
            }
        });
}

// The normal equations H delta = -g of one linearisation, solved with CHOLMOD for a Levenberg
// damping lambda: (H + lambda diag(H)) delta = -g.
class NormalEquations {
public:
    NormalEquations(std::size_t n,
                    tbb::enumerable_thread_specific<Accum>& accs,
                    const Accum& pose_terms) {
        std::vector<Matrix6d> diag = pose_terms.diag;
        std::vector<Vector6d> grad = pose_terms.grad;
        std::unordered_map<std::uint64_t, Matrix6d> off = pose_terms.off;
        cost_ = pose_terms.cost;
        for (auto& acc : accs) {
            for (std::size_t i = 0; i < n; ++i) {
                diag[i] += acc.diag[i];
                grad[i] += acc.grad[i];
            }
            for (const auto& [key, m] : acc.off) {
                auto it = off.find(key);
                if (it == off.end())
                    off.emplace(key, m);
                else
                    it->second += m;
            }
            cost_ += acc.cost;
            sq_dist_ += acc.sq_dist;
        }
        std::vector<Eigen::Triplet<double>> trip;
        trip.reserve(n * 21 + off.size() * 36);
        rhs_.resize(static_cast<Eigen::Index>(6 * n));
        for (std::size_t i = 0; i < n; ++i) {
            const auto o = static_cast<int>(6 * i);
            for (int r = 0; r < 6; ++r) {
                for (int c = r; c < 6; ++c) trip.emplace_back(o + r, o + c, diag[i](r, c));
            }
            rhs_.segment<6>(o) = -grad[i];
        }
        for (const auto& [key, m] : off) {
            const auto i = static_cast<int>(key / n), j = static_cast<int>(key % n);
            for (int r = 0; r < 6; ++r) {
                for (int c = 0; c < 6; ++c) trip.emplace_back(6 * i + r, 6 * j + c, m(r, c));
            }
        }
        H_.resize(static_cast<Eigen::Index>(6 * n), static_cast<Eigen::Index>(6 * n));
        H_.setFromTriplets(trip.begin(), trip.end());
        H_.makeCompressed();
        diag_ = H_.diagonal();
        llt_.analyzePattern(H_);
    }
    double cost() const { return cost_; }
    double sq_dist() const { return sq_dist_; }
    // false if the factorisation fails or the step is not finite.
    bool Solve(double lambda, Eigen::VectorXd* delta) {
        Eigen::SparseMatrix<double> A = H_;
        A.diagonal() = diag_ * (1.0 + lambda) + Eigen::VectorXd::Constant(diag_.size(), 1e-9);
        llt_.factorize(A);
        if (llt_.info() != Eigen::Success) return false;
        *delta = llt_.solve(rhs_);
        return llt_.info() == Eigen::Success && delta->allFinite();
    }

private:
    Eigen::SparseMatrix<double> H_;
    Eigen::VectorXd rhs_, diag_;
    Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>, Eigen::Upper> llt_;
    double cost_ = 0, sq_dist_ = 0;
};

// ---- coarse horizontal search -----------------------------------------------------------------

// For every section whose INS horizontal 1-sigma exceeds coarse_search_min_sigma_m: how well
// each horizontal offset (within coarse_search_m, on a coarse_search_step_m grid) fits its
// points to a height grid of the sections the INS is sure about, the vertical offset taken as
// the median height difference. Score: mean |dz - median dz| over the points that fall on the
// grid (inside a cell's own extent: no extrapolation past swath edges), plus the INS prior on
// the offset, among offsets that see enough of the grid. The offsets of a run of such sections
// are then chosen together under the INS drift model (see below). Closest-point matching alone
// creeps towards offsets of several metres along smooth terrain (each step is bounded by the
// closest-point distances); this puts the sections inside its capture range.
// Returns the world translation per section (zero where not searched).
constexpr double kCoarseScoreUnitM = 0.01;  // fit score unit against the smoothness terms
constexpr double kInfeasible = 1e30;
constexpr double kCoarseExtentMarginM = 0.25;
// Offsets whose points fall on the grid less than this fraction of the best offset's are out (a
// fit on a few points). Not more: a section at the survey's edge overlaps the others only
// partly at its true place, and a larger fraction pushes it inwards.
constexpr double kCoarseMinCoverFraction = 0.25;
constexpr double kCoarseTemperature = 2.0;   // score units (cm of mean deviation)
constexpr double kCoarseMinDriftRw = 0.003;  // m/s/sqrt(s), when the drift term is off
constexpr int kCoarseRefinements = 3;
constexpr double kCoarseWindowSigmas = 3.0;
constexpr double kCoarseMinWindowM = 1.5;

std::vector<Eigen::Vector3d> CoarseSectionSearch(const Input& in,
                                                 const std::vector<Pose>& T,
                                                 const std::vector<Block>& blocks,
                                                 const SlamConfig& cfg,
                                                 std::vector<SlamSection>* sections) {
    const std::size_t nb = blocks.size();
    std::vector<Eigen::Vector3d> offset(nb, Eigen::Vector3d::Zero());
    sections->resize(nb);
    // A section's sigma: the median over its slices (a section where GNSS returns is mostly
    // pulled back already).
    std::vector<double> sigma_h(nb, 0.0);
    for (std::size_t b = 0; b < nb; ++b) {
        std::vector<double> sg;
        for (std::size_t s = blocks[b].s0; s < blocks[b].s1; ++s) {
            sg.push_back(std::max(in.sigma[s](3), in.sigma[s](4)));
        }
        std::nth_element(
            sg.begin(), sg.begin() + static_cast<std::ptrdiff_t>(sg.size() / 2), sg.end());
        sigma_h[b] = sg[sg.size() / 2];
        (*sections)[b].sigma_h_m = sigma_h[b];
        (*sections)[b].searched = sigma_h[b] > cfg.coarse_search_min_sigma_m;
    }
    const double h = cfg.coarse_search_cell_m;
    const double trunc = 0.5 * h;  // deviations beyond half a cell count as a miss
    // Per cell a plane z = c0 + c1 (x - xc) + c2 (y - yc) by least squares (walls are steep).
    struct Cell {
        Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
        Eigen::Vector3d b = Eigen::Vector3d::Zero();
        Eigen::Vector3d c = Eigen::Vector3d::Zero();
        double xc = 0, yc = 0;
        // Extent of the cell's points: a point outside it (beyond kCoarseExtentMarginM) is off
        // the grid rather than an extrapolation of the plane (the grid's edges are swath edges).
        double x0 = std::numeric_limits<double>::max(), x1 = std::numeric_limits<double>::lowest();
        double y0 = std::numeric_limits<double>::max(), y1 = std::numeric_limits<double>::lowest();
        int n = 0;
        bool Covers(double x, double y) const {
            return x >= x0 - kCoarseExtentMarginM && x <= x1 + kCoarseExtentMarginM &&
                   y >= y0 - kCoarseExtentMarginM && y <= y1 + kCoarseExtentMarginM;
        }
    };
    auto cell_of = [h](double x, double y) {
        return std::pair{static_cast<std::int64_t>(std::floor(x / h)),
                         static_cast<std::int64_t>(std::floor(y / h))};
    };
    auto key = [&](double x, double y) {
        const auto [ix, iy] = cell_of(x, y);
        return (static_cast<std::uint64_t>(ix + (1 << 30)) << 32) ^
               static_cast<std::uint64_t>(iy + (1 << 30));
    };
    std::unordered_map<std::uint64_t, Cell> grid;
    auto world = [&](std::size_t s, std::size_t k) {
        return (T[s] * in.points[k].cast<double>()).eval();
    };
    for (std::size_t b = 0; b < nb; ++b) {
        if (sigma_h[b] > cfg.coarse_search_min_sigma_m) continue;
        for (std::size_t s = blocks[b].s0; s < blocks[b].s1; ++s) {
            for (std::size_t k = in.offset[s]; k < in.offset[s + 1]; ++k) {
                const Eigen::Vector3d p = world(s, k);
                Cell& c = grid[key(p.x(), p.y())];
                const auto [ix, iy] = cell_of(p.x(), p.y());
                c.xc = (static_cast<double>(ix) + 0.5) * h;
                c.yc = (static_cast<double>(iy) + 0.5) * h;
                const Eigen::Vector3d u(1.0, p.x() - c.xc, p.y() - c.yc);
                c.A += u * u.transpose();
                c.b += u * p.z();
                c.x0 = std::min(c.x0, p.x());
                c.x1 = std::max(c.x1, p.x());
                c.y0 = std::min(c.y0, p.y());
                c.y1 = std::max(c.y1, p.y());
                ++c.n;
            }
        }
    }
    for (auto it = grid.begin(); it != grid.end();) {
        Cell& c = it->second;
        // Slightly regularised towards a level plane when the points line up.
        Eigen::Matrix3d A = c.A;
        A(1, 1) += 1e-3 * c.n;
        A(2, 2) += 1e-3 * c.n;
        if (c.n >= 4) c.c = A.ldlt().solve(c.b);
        it = c.n < 4 || !c.c.allFinite() ? grid.erase(it) : std::next(it);
    }
    if (grid.empty()) return offset;
    // One grid of candidate offsets for every searched section.
    const long m_steps = std::lround(std::floor(cfg.coarse_search_m / cfg.coarse_search_step_m));
    const long side = 2 * m_steps + 1;
    const auto nc = static_cast<std::size_t>(side * side);
    auto cand = [&](std::size_t c) {
        const auto i = static_cast<long>(c);
        return Eigen::Vector2d(static_cast<double>(i % side - m_steps) * cfg.coarse_search_step_m,
                               static_cast<double>(i / side - m_steps) * cfg.coarse_search_step_m);
    };
    std::vector<std::vector<double>> data(nb), median(nb);
    for (std::size_t b = 0; b < nb; ++b) {
        if (sigma_h[b] <= cfg.coarse_search_min_sigma_m) continue;
        // At most ~2000 points of the section, spread over its slices.
        const std::size_t np = blocks[b].p1 - blocks[b].p0;
        const std::size_t stride = std::max<std::size_t>(1, np / 2000);
        std::vector<Eigen::Vector3d> pts;
        for (std::size_t s = blocks[b].s0; s < blocks[b].s1; ++s) {
            for (std::size_t k = in.offset[s] + (s % stride); k < in.offset[s + 1]; k += stride) {
                pts.push_back(world(s, k));
            }
        }
        if (pts.empty()) continue;
        data[b].assign(nc, 0.0);
        median[b].assign(nc, 0.0);
        std::vector<std::size_t> cover(nc, 0);
        tbb::parallel_for(std::size_t{0}, nc, [&](std::size_t c) {
            const Eigen::Vector2d o = cand(c);
            std::vector<double> dz;
            dz.reserve(pts.size());
            for (const Eigen::Vector3d& p : pts) {
                const double x = p.x() + o.x(), y = p.y() + o.y();
                const auto it = grid.find(key(x, y));
                if (it == grid.end() || !it->second.Covers(x, y)) continue;
                const Cell& g = it->second;
                dz.push_back(g.c(0) + g.c(1) * (x - g.xc) + g.c(2) * (y - g.yc) - p.z());
            }
            double med = 0;
            if (!dz.empty()) {
                auto mid = dz.begin() + static_cast<std::ptrdiff_t>(dz.size() / 2);
                std::nth_element(dz.begin(), mid, dz.end());
                med = *mid;
            }
            // Truncated absolute deviation over the points on the grid, in kCoarseScoreUnitM,
            // plus the INS's own prior on the offset.
            double sum = 0;
            for (double v : dz) sum += std::min(std::abs(v - med), trunc);
            cover[c] = dz.size();
            data[b][c] = dz.empty() ? 0.0
                                    : sum / static_cast<double>(dz.size()) / kCoarseScoreUnitM +
                                          0.5 * o.squaredNorm() / (sigma_h[b] * sigma_h[b]);
            median[b][c] = med;
        });
        // Offsets that see less than half the best coverage are out (a fit on a few points).
        const std::size_t max_cover = *std::max_element(cover.begin(), cover.end());
        if (max_cover < std::max<std::size_t>(20, pts.size() / 10)) {
            data[b].clear();
            continue;
        }
        for (std::size_t c = 0; c < nc; ++c) {
            if (static_cast<double>(cover[c]) <
                kCoarseMinCoverFraction * static_cast<double>(max_cover)) {
                data[b][c] = kInfeasible;
            }
        }
    }
    // Runs of consecutive searched sections, smoothed jointly. Each section's fit surface is
    // summarised as a Gaussian (the mean and covariance of exp(-score / kCoarseTemperature) over
    // its feasible offsets: an along-track valley gives a long axis); the offsets along the run
    // then minimise those terms plus the INS drift model (the velocity error is a random walk, as
    // in the semi-rigid drift term, loosened where the sigma's growth rate bends) plus a zero
    // offset with the INS sigma at the trusted sections on either side. The summaries are taken
    // again within kCoarseWindowSigmas of the smoothed offsets (kCoarseRefinements times), so
    // that a section with two candidate places takes the one its neighbours agree with. Searched
    // sections that did not overlap the grid are carried by their neighbours.
    const double q = std::max(cfg.drift_velocity_random_walk_mps_per_sqrt_s, kCoarseMinDriftRw);
    const double cell_var = cfg.coarse_search_step_m * cfg.coarse_search_step_m / 12.0;
    auto summarise = [&](std::size_t k,
                         const Eigen::Vector2d& centre,
                         double radius,
                         Eigen::Vector2d* mu,
                         Eigen::Matrix2d* cov) {
        double best = kInfeasible;
        for (std::size_t c = 0; c < nc; ++c) {
            if ((cand(c) - centre).norm() <= radius) best = std::min(best, data[k][c]);
        }
        if (best >= kInfeasible) return false;
        double w_sum = 0;
        Eigen::Vector2d m = Eigen::Vector2d::Zero();
        Eigen::Matrix2d s2 = Eigen::Matrix2d::Zero();
        for (std::size_t c = 0; c < nc; ++c) {
            if (data[k][c] >= kInfeasible || (cand(c) - centre).norm() > radius) continue;
            const double w = std::exp(-(data[k][c] - best) / kCoarseTemperature);
            w_sum += w;
            m += w * cand(c);
            s2 += w * cand(c) * cand(c).transpose();
        }
        *mu = m / w_sum;
        *cov = s2 / w_sum - *mu * mu->transpose() + cell_var * Eigen::Matrix2d::Identity();
        return true;
    };
    std::size_t b = 0;
    while (b < nb) {
        if (!(*sections)[b].searched) {
            ++b;
            continue;
        }
        std::size_t e = b;
        while (e < nb && (*sections)[e].searched) ++e;  // run [b, e)
        // Unknowns: the run and its trusted neighbours (offset 0 within their sigma).
        const std::size_t first = b > 0 ? b - 1 : b, last = e < nb ? e : e - 1;
        const std::size_t m = last - first + 1;
        auto centre_t = [&](std::size_t k) { return 0.5 * (blocks[k].t0 + blocks[k].t1); };
        std::vector<Eigen::Vector2d> mu(m, Eigen::Vector2d::Zero()), smooth(m);
        std::vector<Eigen::Matrix2d> info(m, Eigen::Matrix2d::Zero());
        std::vector<Eigen::Matrix2d> post(m, Eigen::Matrix2d::Identity() * 1e6);
        bool any = false;
        for (int pass = 0; pass <= kCoarseRefinements; ++pass) {
            any = false;
            for (std::size_t i = 0; i < m; ++i) {
                const std::size_t k = first + i;
                info[i].setZero();
                mu[i].setZero();
                if (!(*sections)[k].searched) {
                    info[i] =
                        Eigen::Matrix2d::Identity() / std::max(sigma_h[k] * sigma_h[k], cell_var);
                    continue;
                }
                if (data[k].empty()) continue;
                Eigen::Vector2d c0 = Eigen::Vector2d::Zero();
                double radius = std::numeric_limits<double>::infinity();
                if (pass > 0) {
                    c0 = smooth[i];
                    const double sd = std::sqrt(post[i].eigenvalues().real().maxCoeff());
                    radius = std::max(kCoarseMinWindowM, kCoarseWindowSigmas * sd);
                }
                Eigen::Matrix2d cov;
                if (!summarise(k, c0, radius, &mu[i], &cov)) continue;
                info[i] = cov.inverse();
                any = true;
            }
            if (!any) break;
            // Normal equations of the run (2 m unknowns, dense: runs are short).
            Eigen::MatrixXd H = Eigen::MatrixXd::Zero(2 * m, 2 * m);
            Eigen::VectorXd g = Eigen::VectorXd::Zero(2 * m);
            for (std::size_t i = 0; i < m; ++i) {
                const auto r = static_cast<Eigen::Index>(2 * i);
                H.block<2, 2>(r, r) += info[i];
                g.segment<2>(r) += info[i] * mu[i];
            }
            for (std::size_t i = 1; i + 1 < m; ++i) {
                const std::size_t k = first + i;
                const double d0 = std::max(centre_t(k) - centre_t(k - 1), 1e-3);
                const double d1 = std::max(centre_t(k + 1) - centre_t(k), 1e-3);
                const double dm = 0.5 * (d0 + d1);
                // The velocity error changes by about the change of the sigma's growth rate
                // where that is larger (a GNSS outage starting or ending).
                const double bend = std::abs((sigma_h[k + 1] - sigma_h[k]) / d1 -
                                             (sigma_h[k] - sigma_h[k - 1]) / d0);
                const double w = 1.0 / (q * q * dm + bend * bend);
                // r = o_{i+1} / d1 - o_i (1/d0 + 1/d1) + o_{i-1} / d0, per axis.
                const double c[3] = {1.0 / d0, -(1.0 / d0 + 1.0 / d1), 1.0 / d1};
                for (int u = 0; u < 3; ++u) {
                    for (int v = 0; v < 3; ++v) {
                        const auto ru = static_cast<Eigen::Index>(2 * (i - 1 + u));
                        const auto rv = static_cast<Eigen::Index>(2 * (i - 1 + v));
                        H.block<2, 2>(ru, rv) += w * c[u] * c[v] * Eigen::Matrix2d::Identity();
                    }
                }
            }
            H.diagonal().array() += 1e-9;
            const Eigen::LDLT<Eigen::MatrixXd> ldlt(H);
            const Eigen::VectorXd x = ldlt.solve(g);
            const Eigen::MatrixXd P = ldlt.solve(Eigen::MatrixXd::Identity(2 * m, 2 * m));
            for (std::size_t i = 0; i < m; ++i) {
                const auto r = static_cast<Eigen::Index>(2 * i);
                smooth[i] = x.segment<2>(r);
                post[i] = P.block<2, 2>(r, r);
            }
        }
        if (any) {
            for (std::size_t k = b; k < e; ++k) {
                // A run at the survey's start or end with one fitted section leaves a trend
                // barely determined: never more than the search reach, never non-finite.
                if (!smooth[k - first].allFinite()) continue;
                const Eigen::Vector2d o =
                    smooth[k - first].cwiseMax(-cfg.coarse_search_m).cwiseMin(cfg.coarse_search_m);
                // The vertical offset of the nearest candidate; without overlap the INS height.
                double dz = 0;
                if (!data[k].empty()) {
                    const double st = cfg.coarse_search_step_m;
                    const long ix = std::clamp(std::lround(o.x() / st), -m_steps, m_steps);
                    const long iy = std::clamp(std::lround(o.y() / st), -m_steps, m_steps);
                    dz = median[k][static_cast<std::size_t>((iy + m_steps) * side + ix + m_steps)];
                }
                offset[k] = Eigen::Vector3d(o.x(), o.y(), dz);
                (*sections)[k].shifted = true;
                (*sections)[k].coarse_offset_m = offset[k];
            }
        }
        b = e;
    }
    return offset;
}

// ---- consistency score ----------------------------------------------------------------------

// Plane-fit vertical RMS over grid cells that hold query points of passes at least t_d apart:
// per cell, z = a + b x + c y by least squares; score = sqrt(sum SSR / sum (n - 3)).
double ConsistencyScore(const Input& in, const std::vector<Pose>& T, const SlamConfig& cfg) {
    struct Cell {
        Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
        Eigen::Vector3d b = Eigen::Vector3d::Zero();
        double zz = 0;
        double t_min = std::numeric_limits<double>::max();
        double t_max = std::numeric_limits<double>::lowest();
        int n = 0;
    };
    const double h = cfg.score_cell_m;
    const auto stride = static_cast<std::size_t>(cfg.query_stride);
    std::unordered_map<std::uint64_t, Cell> cells;
    for (std::size_t s = 0; s < in.num_slices(); ++s) {
        for (std::size_t q = in.offset[s] + s % stride; q < in.offset[s + 1]; q += stride) {
            const Eigen::Vector3d p = T[s] * in.points[q].cast<double>();
            const double fx = std::floor(p.x() / h), fy = std::floor(p.y() / h);
            const auto ix = static_cast<std::int64_t>(fx), iy = static_cast<std::int64_t>(fy);
            const std::uint64_t key = (static_cast<std::uint64_t>(ix + (1 << 30)) << 32) ^
                                      static_cast<std::uint64_t>(iy + (1 << 30));
            Cell& c = cells[key];
            const Eigen::Vector3d u(1.0, p.x() - (fx + 0.5) * h, p.y() - (fy + 0.5) * h);
            c.A += u * u.transpose();
            c.b += u * p.z();
            c.zz += p.z() * p.z();
            c.t_min = std::min(c.t_min, in.t_s[s]);
            c.t_max = std::max(c.t_max, in.t_s[s]);
            ++c.n;
        }
    }
    double ssr = 0, dof = 0;
    for (const auto& [key, c] : cells) {
        if (c.n < 6 || c.t_max - c.t_min < cfg.min_time_separation_s) continue;
        Eigen::LDLT<Eigen::Matrix3d> ldlt(c.A);
        if (ldlt.info() != Eigen::Success) continue;
        const Eigen::Vector3d beta = ldlt.solve(c.b);
        // Mean-centre z first: zz - b^T beta loses digits at large |z|.
        const double v = std::max(0.0, c.zz - c.b.dot(beta));
        if (!std::isfinite(v)) continue;
        ssr += v;
        dof += c.n - 3;
    }
    return dof > 0 ? std::sqrt(ssr / dof) : 0.0;
}

// ---- one stage ------------------------------------------------------------------------------

struct StageOutcome {
    SlamTermination termination = SlamTermination::kMaxIterations;
    std::string message;
    int iterations = 0;
    std::size_t num_pairs = 0;
    std::size_t num_links = 0;
};

// Poses, world points and k-d trees of the current iterate; pairs and the pair score.
struct Search {
    std::vector<Pair> pairs;
    double score = 0;
    std::size_t num_links = 0;
};

Search SearchPairs(const Input& in,
                   const std::vector<Pose>& T,
                   SlamStage stage,
                   double search_m,
                   std::vector<Block>& blocks,
                   const std::vector<std::uint32_t>& slice_block,
                   std::vector<Eigen::Vector3f>& pw,
                   const SlamConfig& cfg,
                   SlamResult& res) {
    auto t0 = Clock::now();
    tbb::parallel_for(std::size_t{0}, in.num_slices(), [&](std::size_t s) {
        const Eigen::Matrix3f R = T[s].linear().cast<float>();
        const Eigen::Vector3f t = T[s].translation().cast<float>();
        for (std::size_t k = in.offset[s]; k < in.offset[s + 1]; ++k) pw[k] = R * in.points[k] + t;
    });
    BuildTrees(blocks, pw);
    res.timings.trees_s += Seconds(t0);
    t0 = Clock::now();
    SlamConfig it_cfg = cfg;
    it_cfg.max_pair_distance_m = search_m;
    Search out;
    out.pairs = FindPairs(in, blocks, slice_block, pw, it_cfg, cfg.max_pair_distance_m, &out.score);
    std::vector<Pair>& pairs = out.pairs;
    if (stage == SlamStage::kRigid) {
        // Section graph: keep links with enough pairs (overlap heuristic of the paper).
        std::unordered_map<std::uint64_t, std::size_t> link;
        auto key = [&](const Pair& pr) {
            const auto a = std::min(pr.block_a, pr.block_b);
            const auto b = std::max(pr.block_a, pr.block_b);
            return (static_cast<std::uint64_t>(a) << 32) | b;
        };
        for (const Pair& pr : pairs) ++link[key(pr)];
        std::erase_if(pairs, [&](const Pair& pr) {
            return link[key(pr)] < static_cast<std::size_t>(cfg.min_section_link_pairs);
        });
        for (const auto& [k, c] : link) {
            if (c >= static_cast<std::size_t>(cfg.min_section_link_pairs)) ++out.num_links;
        }
    }
    if (cfg.correspondence != CorrespondenceType::kPointToPoint) {
        tbb::parallel_for(std::size_t{0}, pairs.size(), [&](std::size_t k) {
            Pair& pr = pairs[k];
            pr.normal_b = LocalNormal(blocks[pr.block_b], pw, pr.point_b, cfg.normal_neighbours);
            if (cfg.correspondence == CorrespondenceType::kGicp) {
                pr.normal_a =
                    LocalNormal(blocks[pr.block_a], pw, pr.point_a, cfg.normal_neighbours);
            }
        });
        std::erase_if(pairs, [&](const Pair& pr) {
            return pr.normal_b.isZero() ||
                   (cfg.correspondence == CorrespondenceType::kGicp && pr.normal_a.isZero());
        });
    }
    res.timings.search_s += Seconds(t0);
    return out;
}

// Total cost (INS terms and robust pair terms) of the parametrisation p on fixed pairs.
double CostAt(const Input& in,
              const Param& p,
              const std::vector<Pair>& pairs,
              const SlamConfig& cfg) {
    const std::vector<Pose> T = SlicePoses(p);
    Accum pose_terms(0);
    AddPoseTerms(in, p, T, cfg, /*linearise=*/false, pose_terms);
    tbb::enumerable_thread_specific<Accum> accs([] { return Accum(0); });
    AddPairTerms(in, p, T, pairs, cfg, /*linearise=*/false, accs);
    double cost = pose_terms.cost;
    for (const Accum& acc : accs) cost += acc.cost;
    return cost;
}

// Gauss-Newton with re-found correspondences (ICP-like). Guards, so that the result is never
// worse than the start:
//  - a step is taken only if it lowers the total cost on the pairs it was computed from;
//    otherwise the Levenberg damping grows (kMaxDampingRetries times at most, then the stage
//    ends with kNoImprovement);
//  - the pair score (truncated closest-point RMS at max_pair_distance_m over the overlap) of
//    every iterate is measured with the next search; the best iterate is kept, and the stage
//    ends after score_patience iterations without a better one.
StageOutcome RunStage(const Input& in,
                      Param& p,
                      SlamStage stage,
                      int max_iterations,
                      double rigid_d0_m,
                      std::vector<Block>& blocks,
                      const std::vector<std::uint32_t>& slice_block,
                      const SlamConfig& cfg,
                      double* best_score,
                      SlamResult& res) {
    constexpr int kMaxDampingRetries = 8;
    constexpr double kMinDamping = 1e-6;
    StageOutcome out;
    const std::size_t n = p.num_nodes();
    std::vector<Eigen::Matrix3d> best_R = p.Rc;
    std::vector<Eigen::Vector3d> best_t = p.tc;
    int stalled = 0;
    double lambda = kMinDamping;
    bool stop = false;
    std::vector<Eigen::Vector3f> pw(in.points.size());
    for (int it = 1;; ++it) {
        double search_m = cfg.max_pair_distance_m;
        if (stage == SlamStage::kRigid && max_iterations > 1 && it <= max_iterations) {
            // d_i = d_0 (d_max / d_0)^((i - 1) / (n - 1)): coarse to fine.
            const double f = static_cast<double>(it - 1) / static_cast<double>(max_iterations - 1);
            search_m = rigid_d0_m * std::pow(cfg.max_pair_distance_m / rigid_d0_m, f);
        }
        const std::vector<Pose> T = SlicePoses(p);
        Search found = SearchPairs(in, T, stage, search_m, blocks, slice_block, pw, cfg, res);
        if (it == 1 && res.iterations.empty()) {
            *best_score = found.score;
            res.initial_pair_score_m = found.score;
        }
        if (it > 1) {
            // The score of the previous step's result.
            SlamIteration& rec = res.iterations.back();
            rec.pair_score_m = found.score;
            // The lowest score is kept; only a gain beyond score_tolerance resets the patience.
            const bool gain = found.score < *best_score * (1.0 - cfg.score_tolerance);
            rec.best = found.score < *best_score;
            if (rec.best) {
                *best_score = found.score;
                best_R = p.Rc;
                best_t = p.tc;
            }
            if (gain) {
                stalled = 0;
            } else if (++stalled >= cfg.score_patience && !stop &&
                       search_m <= cfg.max_pair_distance_m * (1.0 + 1e-9)) {
                // (Not while the rigid stage's pair distance is still shrinking: the truncated
                // score sees little of the coarse alignment.)
                out.termination = SlamTermination::kScoreStalled;
                out.message = "pair score did not improve by more than " +
                              std::to_string(cfg.score_tolerance) + " (relative) for " +
                              std::to_string(cfg.score_patience) + " iterations; best iterate kept";
                stop = true;
            }
        }
        if (stop || it > max_iterations) break;
        std::vector<Pair>& pairs = found.pairs;
        out.num_links = std::max(out.num_links, found.num_links);
        out.num_pairs = pairs.size();
        if (pairs.empty()) {
            out.termination = SlamTermination::kNoOverlap;
            out.message = "no point pairs at least " + std::to_string(cfg.min_time_separation_s) +
                          " s apart and closer than " + std::to_string(search_m) + " m";
            break;
        }
        auto t0 = Clock::now();
        Accum pose_terms(n);
        AddPoseTerms(in, p, T, cfg, /*linearise=*/true, pose_terms);
        tbb::enumerable_thread_specific<Accum> accs([n] { return Accum(n); });
        AddPairTerms(in, p, T, pairs, cfg, /*linearise=*/true, accs);
        res.timings.build_s += Seconds(t0);
        t0 = Clock::now();
        NormalEquations ne(n, accs, pose_terms);
        res.timings.build_s += Seconds(t0);
        SlamIteration rec;
        rec.stage = stage;
        rec.iteration = it;
        rec.num_pairs = pairs.size();
        rec.cost = ne.cost();
        rec.pair_rms_m = std::sqrt(ne.sq_dist() / static_cast<double>(pairs.size()));
        bool accepted = false, solved = false;
        Param trial = p;
        double max_rot = 0, max_trans = 0;
        for (int attempt = 0; attempt <= kMaxDampingRetries && !accepted; ++attempt) {
            t0 = Clock::now();
            Eigen::VectorXd delta;
            const bool ok = ne.Solve(lambda, &delta);
            res.timings.solve_s += Seconds(t0);
            if (!ok) {
                lambda *= 10.0;
                continue;
            }
            solved = true;
            max_rot = max_trans = 0;
            for (std::size_t k = 0; k < n; ++k) {
                const Vector6d d = delta.segment<6>(static_cast<Eigen::Index>(6 * k));
                trial.Rc[k] = ExpSO3(d.head<3>()) * p.Rc[k];
                trial.tc[k] = p.tc[k] + d.tail<3>();
                max_rot = std::max(max_rot, d.head<3>().norm());
                max_trans = std::max(max_trans, d.tail<3>().norm());
            }
            t0 = Clock::now();
            rec.cost_after = CostAt(in, trial, pairs, cfg);
            res.timings.build_s += Seconds(t0);
            accepted = rec.cost_after < rec.cost;
            if (!accepted) {
                lambda *= 10.0;
                ++rec.rejected_steps;
            }
        }
        rec.damping = lambda;
        out.iterations = it;
        if (!accepted) {
            rec.cost_after = rec.cost;
            rec.pair_score_m = found.score;  // no step taken: the iterate is unchanged
            res.iterations.push_back(rec);
            out.termination =
                solved ? SlamTermination::kNoImprovement : SlamTermination::kSolverFailed;
            out.message = solved ? "no step lowered the cost on the current pairs (damping up to " +
                                       std::to_string(lambda / 10.0) + "); best iterate kept"
                                 : "CHOLMOD could not factorise the normal equations";
            break;
        }
        lambda = std::max(kMinDamping, lambda / 10.0);
        p.Rc = trial.Rc;
        p.tc = trial.tc;
        rec.max_step_rotation_rad = max_rot;
        rec.max_step_translation_m = max_trans;
        t0 = Clock::now();
        rec.consistency_m = ConsistencyScore(in, SlicePoses(p), cfg);
        res.timings.score_s += Seconds(t0);
        res.iterations.push_back(rec);
        if (max_rot < cfg.convergence_rotation_rad && max_trans < cfg.convergence_translation_m) {
            out.termination = SlamTermination::kConverged;
            out.message = "pose updates below the convergence thresholds";
            stop = true;  // score this iterate, then stop
        } else if (cfg.progress && !cfg.progress(static_cast<int>(stage), it)) {
            out.termination = SlamTermination::kCancelled;
            out.message = "cancelled";
            stop = true;
        } else if (it == max_iterations) {
            out.message = "iteration budget spent";
        }
    }
    p.Rc = best_R;
    p.tc = best_t;
    return out;
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

}  // namespace

const char* ToString(SlamTermination t) {
    switch (t) {
        case SlamTermination::kConverged:
            return "converged";
        case SlamTermination::kMaxIterations:
            return "max_iterations";
        case SlamTermination::kScoreStalled:
            return "score_stalled";
        case SlamTermination::kNoImprovement:
            return "no_improvement";
        case SlamTermination::kNoOverlap:
            return "no_overlap";
        case SlamTermination::kSolverFailed:
            return "solver_failed";
        case SlamTermination::kCancelled:
            return "cancelled";
        case SlamTermination::kInvalidInput:
            return "invalid_input";
    }
    return "unknown";
}

std::vector<std::string> SlamConfig::Validate() const {
    std::vector<std::string> p;
    if (!(min_time_separation_s >= 0)) p.push_back("min_time_separation_s must be >= 0");
    if (!(max_pair_distance_m > 0)) p.push_back("max_pair_distance_m must be > 0");
    if (!(rigid_max_pair_distance_m >= max_pair_distance_m)) {
        p.push_back("rigid_max_pair_distance_m must be >= max_pair_distance_m");
    }
    if (!(section_length_s > 0)) p.push_back("section_length_s must be > 0");
    if (rigid_iterations < 0) p.push_back("rigid_iterations must be >= 0");
    if (min_section_link_pairs < 1) p.push_back("min_section_link_pairs must be >= 1");
    if (bin_slices < 1) p.push_back("bin_slices must be >= 1");
    if (max_iterations < 0) p.push_back("max_iterations must be >= 0");
    if (!(convergence_rotation_rad >= 0)) p.push_back("convergence_rotation_rad must be >= 0");
    if (!(convergence_translation_m >= 0)) p.push_back("convergence_translation_m must be >= 0");
    if (normal_neighbours < 3) p.push_back("normal_neighbours must be >= 3");
    if (!(point_sigma_m > 0)) p.push_back("point_sigma_m must be > 0");
    if (!(gicp_tangent_sigma_m > 0)) p.push_back("gicp_tangent_sigma_m must be > 0");
    if (!(robust_width > 0)) p.push_back("robust_width must be > 0");
    if (query_stride < 1) p.push_back("query_stride must be >= 1");
    if (!(ins_correlation_time_s > 0)) p.push_back("ins_correlation_time_s must be > 0");
    if (!(ins_sigma_scale > 0)) p.push_back("ins_sigma_scale must be > 0");
    if (!(min_relative_rotation_sigma_rad > 0)) {
        p.push_back("min_relative_rotation_sigma_rad must be > 0");
    }
    if (!(min_relative_translation_sigma_m > 0)) {
        p.push_back("min_relative_translation_sigma_m must be > 0");
    }
    if (!(ins_sigma_recovery_time_s >= 0)) p.push_back("ins_sigma_recovery_time_s must be >= 0");
    if (!(drift_velocity_random_walk_mps_per_sqrt_s >= 0)) {
        p.push_back("drift_velocity_random_walk_mps_per_sqrt_s must be >= 0");
    }
    if (!(absolute_sigma_scale > 0)) p.push_back("absolute_sigma_scale must be > 0");
    if (!(coarse_search_m >= 0)) p.push_back("coarse_search_m must be >= 0");
    if (!(coarse_search_step_m > 0)) p.push_back("coarse_search_step_m must be > 0");
    if (!(coarse_search_cell_m > 0)) p.push_back("coarse_search_cell_m must be > 0");
    if (!(coarse_search_min_sigma_m > 0)) p.push_back("coarse_search_min_sigma_m must be > 0");
    if (!(score_cell_m > 0)) p.push_back("score_cell_m must be > 0");
    if (score_patience < 1) p.push_back("score_patience must be >= 1");
    if (!(score_tolerance >= 0 && score_tolerance < 1)) {
        p.push_back("score_tolerance must be in [0, 1)");
    }
    if (num_threads < 0) p.push_back("num_threads must be >= 0 (0 = auto)");
    return p;
}

std::vector<Eigen::Vector3f> PointsWorld(const std::vector<Slice>& slices,
                                         const std::vector<SlamPose>& trajectory) {
    std::vector<Eigen::Vector3f> out;
    for (const SlamPose& sp : trajectory) {
        if (sp.input_index >= slices.size()) continue;
        const Eigen::Isometry3f T = sp.T_world_vehicle.cast<float>();
        for (const auto& x : slices[sp.input_index].points_vehicle) {
            if (x.allFinite()) out.push_back(T * x);
        }
    }
    return out;
}

SlamResult RunSlam(const std::vector<Slice>& slices, const SlamConfig& cfg) {
    const auto t_start = Clock::now();
    SlamResult res;
    const auto problems = cfg.Validate();
    if (!problems.empty()) {
        res.termination = SlamTermination::kInvalidInput;
        res.message = "invalid config: " + problems.front();
        for (std::size_t i = 1; i < problems.size(); ++i) res.message += "; " + problems[i];
        return res;
    }
    if (slices.empty()) {
        res.termination = SlamTermination::kInvalidInput;
        res.message = "no slices";
        return res;
    }
    for (std::size_t i = 0; i < slices.size(); ++i) {
        if (!std::isfinite(slices[i].gps_time_s) || !FinitePose(slices[i].T_world_vehicle) ||
            !slices[i].pose_sigma.allFinite() || (slices[i].pose_sigma.array() <= 0).any()) {
            res.termination = SlamTermination::kInvalidInput;
            res.message = "slice " + std::to_string(i) +
                          ": non-finite time or pose, or a pose sigma that is not > 0";
            return res;
        }
    }
    std::optional<tbb::global_control> threads;
    if (cfg.num_threads > 0) {
        threads.emplace(tbb::global_control::max_allowed_parallelism,
                        static_cast<std::size_t>(cfg.num_threads));
    }

    // Sort by time (ties by input index) so that the result does not depend on input order.
    Input in;
    std::vector<std::size_t> order(slices.size());
    std::iota(order.begin(), order.end(), std::size_t{0});
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
        return slices[a].gps_time_s < slices[b].gps_time_s;
    });
    in.input_index = order;
    in.offset.push_back(0);
    for (std::size_t i : order) {
        const Slice& s = slices[i];
        in.t_s.push_back(s.gps_time_s);
        Pose T = s.T_world_vehicle;
        T.linear() = Eigen::Quaterniond(T.linear()).normalized().toRotationMatrix();
        in.T_ins.push_back(T);
        in.sigma.push_back(s.pose_sigma);
        for (const auto& x : s.points_vehicle) {
            if (x.allFinite()) in.points.push_back(x);
        }
        in.offset.push_back(in.points.size());
    }
    const std::size_t ns = in.num_slices();
    in.breaks = FindBreaks(in.t_s, in.sigma, cfg.coarse_search_min_sigma_m);
    in.sigma_floor = in.sigma.front();
    for (const Vector6d& sg : in.sigma) in.sigma_floor = in.sigma_floor.cwiseMin(sg);
    if (cfg.ins_sigma_recovery_time_s > 0) {
        for (std::size_t s = 1; s < ns; ++s) {
            const double decay =
                std::exp(-(in.t_s[s] - in.t_s[s - 1]) / cfg.ins_sigma_recovery_time_s);
            in.sigma[s] = in.sigma[s].cwiseMax(decay * in.sigma[s - 1]);
        }
    }

    std::vector<Block> blocks = MakeBlocks(in, cfg.section_length_s);
    std::vector<std::uint32_t> slice_block(ns);
    for (std::uint32_t b = 0; b < blocks.size(); ++b) {
        for (std::size_t s = blocks[b].s0; s < blocks[b].s1; ++s) slice_block[s] = b;
    }
    res.num_sections = blocks.size();
    res.sections.resize(blocks.size());
    for (std::size_t b = 0; b < blocks.size(); ++b) {
        res.sections[b].t0_s = blocks[b].t0;
        res.sections[b].t1_s = blocks[b].t1;
    }

    auto t0 = Clock::now();
    res.initial_consistency_m = ConsistencyScore(in, in.T_ins, cfg);
    res.timings.score_s += Seconds(t0);
    double best_score = 0;  // pair score, set by the first search
    std::vector<Pose> current = in.T_ins;

    // Stage 1: rigid sections, rotating about the section's mean position; or, with
    // rigid_interpolate_sections, one correction per section centre, interpolated in time
    // between centres (the corrected track stays continuous).
    StageOutcome rigid;
    rigid.termination = SlamTermination::kConverged;
    if (cfg.rigid_iterations > 0) {
        std::vector<std::size_t> nodes;
        // Interpolated: a node at each section centre, but at the start of a section that
        // starts at a GNSS recovery (the INS error is continuous there, its rate is not).
        for (const Block& b : blocks) {
            nodes.push_back(
                cfg.rigid_interpolate_sections && !in.IsBreak(b.s0) ? (b.s0 + b.s1 - 1) / 2 : b.s0);
        }
        Param p = MakeParam(current, nodes);
        for (std::size_t b = 0; b < blocks.size(); ++b) {
            Eigen::Vector3d c = Eigen::Vector3d::Zero();
            for (std::size_t s = blocks[b].s0; s < blocks[b].s1; ++s) c += current[s].translation();
            c /= static_cast<double>(blocks[b].s1 - blocks[b].s0);
            for (std::size_t s = blocks[b].s0; s < blocks[b].s1; ++s) {
                p.pivot[s] = c;
                p.k0[s] = p.k1[s] = static_cast<int>(b);
            }
        }
        if (cfg.rigid_interpolate_sections) {
            std::size_t k = 0;
            for (std::size_t s = 0; s < ns; ++s) {
                while (k + 1 < nodes.size() && nodes[k + 1] <= s) ++k;
                p.pivot[s] = current[s].translation();
                p.k0[s] = static_cast<int>(k);
                p.k1[s] = static_cast<int>(k);
                p.alpha[s] = 0.0;
                if (s > nodes[k] && k + 1 < nodes.size()) {
                    p.k1[s] = static_cast<int>(k + 1);
                    p.alpha[s] = (in.t_s[s] - in.t_s[nodes[k]]) /
                                 std::max(in.t_s[nodes[k + 1]] - in.t_s[nodes[k]], 1e-9);
                }
            }
        }
        if (cfg.coarse_search_m > 0) {
            t0 = Clock::now();
            const std::vector<Eigen::Vector3d> shift =
                CoarseSectionSearch(in, current, blocks, cfg, &res.sections);
            for (const SlamSection& sec : res.sections) {
                res.num_sections_searched += sec.searched ? 1 : 0;
                res.num_sections_shifted += sec.shifted ? 1 : 0;
            }
            for (std::size_t b = 0; b < blocks.size(); ++b) p.tc[b] = shift[b];
            res.timings.coarse_search_s = Seconds(t0);
        }
        // Coarse to fine from 3 INS sigmas (the largest section median), within
        // [max_pair_distance_m, rigid_max_pair_distance_m]: no wide search where GNSS was good.
        double sigma_max = 0;
        for (const Block& b : blocks) {
            std::vector<double> sg;
            for (std::size_t s = b.s0; s < b.s1; ++s) {
                sg.push_back(std::max(in.sigma[s](3), in.sigma[s](4)));
            }
            std::nth_element(
                sg.begin(), sg.begin() + static_cast<std::ptrdiff_t>(sg.size() / 2), sg.end());
            sigma_max = std::max(sigma_max, sg[sg.size() / 2]);
        }
        const double d0 =
            std::clamp(3.0 * sigma_max, cfg.max_pair_distance_m, cfg.rigid_max_pair_distance_m);
        rigid = RunStage(in,
                         p,
                         SlamStage::kRigid,
                         cfg.rigid_iterations,
                         d0,
                         blocks,
                         slice_block,
                         cfg,
                         &best_score,
                         res);
        res.rigid_iterations = rigid.iterations;
        res.num_section_links = rigid.num_links;
        current = SlicePoses(p);
    }

    // Stage 2: semi-rigid, one pose per bin, slices interpolated inside a bin.
    StageOutcome semi;
    semi.termination = rigid.termination;
    semi.message = rigid.message;
    if (cfg.max_iterations > 0 && rigid.termination != SlamTermination::kNoOverlap &&
        rigid.termination != SlamTermination::kCancelled) {
        // Bins of bin_slices, restarted at every GNSS recovery with bins of 1, 1, 2, 4, ...
        // slices (the INS error falls fast there); slice poses are interpolated between bin
        // starts.
        std::vector<std::size_t> starts;
        const auto bin = static_cast<std::size_t>(cfg.bin_slices);
        std::size_t since_break = ns;  // slices since the last recovery
        for (std::size_t s = 0; s < ns;) {
            if (in.IsBreak(s)) since_break = 0;
            starts.push_back(s);
            const std::size_t len = std::clamp<std::size_t>(since_break, 1, bin);
            std::size_t next = s + 1;
            while (next < ns && next < s + len && !in.IsBreak(next)) ++next;
            since_break += next - s;
            s = next;
        }
        Param p = MakeParam(current, starts);
        std::size_t k = 0;
        for (std::size_t s = 0; s < ns; ++s) {
            while (k + 1 < starts.size() && starts[k + 1] <= s) ++k;
            p.pivot[s] = current[s].translation();
            p.k0[s] = p.k1[s] = static_cast<int>(k);
            p.alpha[s] = 0.0;
            if (k + 1 < starts.size() && s > starts[k]) {
                p.k1[s] = static_cast<int>(k + 1);
                p.alpha[s] = static_cast<double>(s - starts[k]) /
                             static_cast<double>(starts[k + 1] - starts[k]);
            }
        }
        res.num_poses = starts.size();
        semi = RunStage(in,
                        p,
                        SlamStage::kSemiRigid,
                        cfg.max_iterations,
                        cfg.max_pair_distance_m,
                        blocks,
                        slice_block,
                        cfg,
                        &best_score,
                        res);
        res.semi_rigid_iterations = semi.iterations;
        current = SlicePoses(p);
        if (semi.message.empty()) semi.message = "iteration budget spent";
    }
    res.num_pairs = semi.num_pairs != 0 ? semi.num_pairs : rigid.num_pairs;
    res.termination = semi.termination;
    res.message = semi.message;
    if (rigid.termination == SlamTermination::kNoOverlap) {
        res.message = "rigid stage: " + rigid.message + "; trajectory unchanged";
    }
    res.final_pair_score_m = res.iterations.empty() ? res.initial_pair_score_m : best_score;
    t0 = Clock::now();
    res.final_consistency_m = ConsistencyScore(in, current, cfg);
    res.timings.score_s += Seconds(t0);
    res.trajectory.resize(ns);
    for (std::size_t s = 0; s < ns; ++s) {
        res.trajectory[s].gps_time_s = in.t_s[s];
        res.trajectory[s].T_world_vehicle = current[s];
        res.trajectory[s].input_index = in.input_index[s];
    }
    res.timings.total_s = Seconds(t_start);
    return res;
}

}  // namespace pitmap::proc::slam
