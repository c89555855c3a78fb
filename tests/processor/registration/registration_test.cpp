// SPDX-License-Identifier: MIT
// The registration core shared by calibration and SLAM: neighbour search against brute force,
// plane fits far from the origin, grid keys, GICP information, the block normal equations and
// the damped CHOLMOD solver against dense Eigen solves, robust kernels.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cstdint>
#include <random>
#include <set>
#include <vector>

#include "processor/registration/correspondence.hpp"
#include "processor/registration/grid_key.hpp"
#include "processor/registration/neighbours.hpp"
#include "processor/registration/normal_equations.hpp"
#include "processor/registration/normals.hpp"
#include "processor/registration/robust.hpp"

namespace pitmap::proc::reg {
namespace {

std::vector<Eigen::Vector3d> RandomPoints(int n, unsigned seed, double scale) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-scale, scale);
    std::vector<Eigen::Vector3d> p(static_cast<std::size_t>(n));
    for (auto& x : p) x = Eigen::Vector3d(u(rng), u(rng), u(rng));
    return p;
}

TEST(PointIndex, NearestAndRadiusMatchBruteForce) {
    const auto pts = RandomPoints(2000, 1, 10.0);
    const PointIndex3d index(pts.data(), pts.size());
    ASSERT_EQ(index.size(), pts.size());
    const auto queries = RandomPoints(50, 2, 11.0);
    std::vector<PointIndex3d::Hit> hits;
    for (const auto& q : queries) {
        std::vector<std::pair<double, std::size_t>> all;
        for (std::size_t i = 0; i < pts.size(); ++i) all.push_back({(pts[i] - q).squaredNorm(), i});
        std::sort(all.begin(), all.end());
        std::size_t idx[5];
        double d2[5];
        ASSERT_EQ(index.Nearest(q, 5, idx, d2), 5u);
        for (int k = 0; k < 5; ++k) {
            EXPECT_EQ(idx[k], all[static_cast<std::size_t>(k)].second);
            EXPECT_NEAR(d2[k], all[static_cast<std::size_t>(k)].first, 1e-9);
        }
        const double r2 = 4.0;
        index.WithinRadius(q, r2, hits);
        std::set<std::size_t> got, want;
        for (const auto& [i, d] : hits) got.insert(i);
        for (const auto& [d, i] : all) {
            if (d < r2) want.insert(i);
        }
        EXPECT_EQ(got, want);
    }
}

// A tree with 32-bit indices (SLAM's sections) is the same tree: the same neighbours in the same
// order, the same bounded nearest and the same points within a radius, in the same order, as
// with std::size_t; its permutation takes half the bytes.
TEST(PointIndex, ThirtyTwoBitIndicesGiveTheSameAnswers) {
    std::vector<Eigen::Vector3f> pts;
    for (const auto& x : RandomPoints(5000, 7, 10.0)) pts.push_back(x.cast<float>());
    for (int i = 0; i < 500; ++i) pts.emplace_back(i % 10, (i / 10) % 10, i / 100);  // ties
    const PointIndex<float> wide(pts.data(), pts.size());
    const PointIndex<float, std::uint32_t> narrow(pts.data(), pts.size());
    EXPECT_LT(narrow.memory_bytes(), wide.memory_bytes());
    EXPECT_GE(wide.memory_bytes() - narrow.memory_bytes(), 4 * pts.size());
    std::vector<PointIndex<float>::Hit> hits_wide, hits_narrow;
    for (const auto& qd : RandomPoints(300, 8, 12.0)) {
        const Eigen::Vector3f q = qd.cast<float>();
        for (const std::size_t k : {std::size_t{1}, std::size_t{24}, std::size_t{80}}) {
            std::vector<std::size_t> ia(k), ib(k);
            std::vector<float> da(k), db(k);
            const std::size_t na = wide.Nearest(q, k, ia.data(), da.data());
            const std::size_t nb = narrow.Nearest(q, k, ib.data(), db.data());
            ASSERT_EQ(na, nb);
            for (std::size_t i = 0; i < na; ++i) {
                EXPECT_EQ(ia[i], ib[i]);
                EXPECT_EQ(da[i], db[i]);
            }
        }
        for (const float bound : {0.05f, 1.0f, 1e9f}) {
            std::size_t ia = 0, ib = 0;
            float da = 0, db = 0;
            ASSERT_EQ(wide.NearestWithin(q, bound, &ia, &da),
                      narrow.NearestWithin(q, bound, &ib, &db));
            EXPECT_EQ(ia, ib);
            EXPECT_EQ(da, db);
        }
        wide.WithinRadius(q, 2.0f, hits_wide);
        narrow.WithinRadius(q, 2.0f, hits_narrow);
        EXPECT_EQ(hits_wide, hits_narrow);
    }
}

// The bounded nearest search finds the nearest point exactly when it lies strictly inside the
// bound, and agrees with Nearest(q, 1) there (same point on ties: a grid has many).
TEST(PointIndex, NearestWithinABoundMatchesBruteForceAndNearest) {
    auto pts = RandomPoints(3000, 3, 10.0);
    for (int i = 0; i < 500; ++i) pts.emplace_back(i % 10, (i / 10) % 10, i / 100);  // ties
    const PointIndex3d index(pts.data(), pts.size());
    auto queries = RandomPoints(200, 4, 14.0);
    for (int i = 0; i < 50; ++i) queries.emplace_back(i % 10 + 0.5, (i / 10) % 10, 0.0);
    int found = 0, missed = 0;
    for (const auto& q : queries) {
        double best = 1e300;
        for (const auto& x : pts) best = std::min(best, (x - q).squaredNorm());
        std::size_t knn_idx = 0;
        double knn_d2 = 0;
        ASSERT_EQ(index.Nearest(q, 1, &knn_idx, &knn_d2), 1u);
        for (const double bound : {0.01, 0.3, 1.0, 4.0, 1e9}) {
            std::size_t idx = 0;
            double d2 = 0;
            const bool hit = index.NearestWithin(q, bound, &idx, &d2);
            ASSERT_EQ(hit, best < bound) << "bound " << bound;
            if (!hit) {
                ++missed;
                continue;
            }
            ++found;
            EXPECT_DOUBLE_EQ(d2, best);
            EXPECT_EQ(idx, knn_idx);
        }
    }
    EXPECT_GT(found, 100);
    EXPECT_GT(missed, 100);
}

// With a filter, the nearest admitted point within the bound, as a brute force over the
// admitted points finds it; rejected points never shrink the bound (the nearest point of all
// is often a rejected one here).
TEST(PointIndex, NearestWithinIfFindsTheNearestAdmittedPoint) {
    const auto pts = RandomPoints(4000, 5, 10.0);
    const PointIndex3d index(pts.data(), pts.size());
    const auto queries = RandomPoints(300, 6, 12.0);
    auto admit = [](std::size_t i) { return i % 3 == 0; };  // a third of the points
    int found = 0, nearest_rejected = 0;
    for (const auto& q : queries) {
        double best_all = 1e300, best = 1e300;
        std::size_t best_i = 0;
        for (std::size_t i = 0; i < pts.size(); ++i) {
            const double d2 = (pts[i] - q).squaredNorm();
            best_all = std::min(best_all, d2);
            if (admit(i) && d2 < best) {
                best = d2;
                best_i = i;
            }
        }
        nearest_rejected += best_all < best;
        for (const double bound : {0.05, 0.5, 2.0, 1e9}) {
            std::size_t idx = 0;
            double d2 = 0;
            const bool hit = index.NearestWithinIf(q, bound, admit, &idx, &d2);
            ASSERT_EQ(hit, best < bound) << "bound " << bound;
            if (!hit) continue;
            ++found;
            EXPECT_TRUE(admit(idx));
            EXPECT_EQ(idx, best_i);
            EXPECT_DOUBLE_EQ(d2, best);
        }
    }
    EXPECT_GT(found, 300);
    EXPECT_GT(nearest_rejected, 100);
}

TEST(PointIndex, FloatPointsAndFewerThanAsked) {
    std::vector<Eigen::Vector3f> pts = {{0, 0, 0}, {1, 0, 0}};
    const PointIndex3f index(pts.data(), pts.size());
    std::size_t idx[4];
    float d2[4];
    EXPECT_EQ(index.Nearest(Eigen::Vector3f(0.9f, 0, 0), 4, idx, d2), 2u);
    EXPECT_EQ(idx[0], 1u);
}

// A tilted plane 100 km from the origin with centimetre spread: the normal to 1e-6 rad
// (a one-pass covariance of raw coordinates would lose every digit here).
TEST(PlaneFit, TiltedPlaneFarFromTheOrigin) {
    const Eigen::Vector3d n_true = Eigen::Vector3d(0.3, -0.2, 1.0).normalized();
    const Eigen::Vector3d u = n_true.unitOrthogonal(), v = n_true.cross(u);
    const Eigen::Vector3d origin(1e5, -2e5, 50.0);
    MomentAccumulator m;
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> a(-0.05, 0.05);
    for (int i = 0; i < 200; ++i) m.Add(origin + a(rng) * u + a(rng) * v);
    const PlaneFit f = FitPlane(m);
    ASSERT_TRUE(f.valid);
    EXPECT_EQ(f.count, 200);
    EXPECT_LT((f.normal - n_true).norm(), 1e-6);
    EXPECT_GE(f.normal.z(), 0.0);
    EXPECT_TRUE(f.Planar(0.1));
    EXPECT_LT((f.mean - origin).norm(), 0.01);
}

TEST(PlaneFit, TooFewPointsOrALineIsNotAPlane) {
    MomentAccumulator two;
    two.Add({0, 0, 0});
    two.Add({1, 0, 0});
    EXPECT_FALSE(FitPlane(two).valid);
    MomentAccumulator line;
    for (int i = 0; i < 20; ++i) line.Add({0.1 * i, 0.2 * i, 0.0});
    const PlaneFit f = FitPlane(line);
    EXPECT_TRUE(f.valid);
    EXPECT_FALSE(f.Planar(0.1));  // two zero eigenvalues: no plane
}

TEST(GridKey, DistinctNeighboursAndSymmetricPairs) {
    std::set<std::uint64_t> keys;
    for (int ix = -3; ix <= 3; ++ix) {
        for (int iy = -3; iy <= 3; ++iy) keys.insert(CellKey(ix, iy));
    }
    EXPECT_EQ(keys.size(), 49u);
    EXPECT_EQ(CellKeyOf(-0.5, 2.5, 1.0), CellKey(-1, 2));
    EXPECT_EQ(CellKeyOf(-0.5, 2.5, 4.0), CellKey(-1, 0));
    EXPECT_NE(CellKey(1, 0), CellKey(0, 1));
    EXPECT_EQ(UnorderedPairKey(3, 9), UnorderedPairKey(9, 3));
    EXPECT_NE(UnorderedPairKey(3, 9), UnorderedPairKey(3, 8));
}

TEST(Gicp, InformationAlongAndAcrossTheSurface) {
    const Eigen::Vector3d n(0, 0, 1);
    const Eigen::Matrix3d I = GicpInformation(n, n, 0.05, 0.5);
    EXPECT_NEAR(I(2, 2), 1.0 / (2 * 0.05 * 0.05), 1e-9);
    EXPECT_NEAR(I(0, 0), 1.0 / (2 * 0.5 * 0.5), 1e-9);
    EXPECT_NEAR(I(0, 2), 0.0, 1e-12);
}

// A random sparse least-squares problem: residuals on 1-3 blocks each, some blocks repeated.
// Small systems hold their off-diagonal blocks densely, large ones (over 512 unknowns) in a
// hash map; the terms are also split over two systems and merged, as SLAM's threads do.
template <int B>
void CheckAgainstDense(unsigned seed, int kBlocks = 7) {
    constexpr int M = 2;
    std::mt19937 rng(seed);
    std::normal_distribution<double> g;
    std::uniform_int_distribution<int> pick(0, kBlocks - 1);
    BlockSystem<B> sys(static_cast<std::size_t>(kBlocks));
    BlockSystem<B> half_a(static_cast<std::size_t>(kBlocks));
    BlockSystem<B> half_b(static_cast<std::size_t>(kBlocks));
    Eigen::MatrixXd H = Eigen::MatrixXd::Zero(B * kBlocks, B * kBlocks);
    Eigen::VectorXd grad = Eigen::VectorXd::Zero(B * kBlocks);
    for (int t = 0; t < 9 * kBlocks; ++t) {
        const int count = 1 + t % 3;
        int blocks[3];
        Eigen::Matrix<double, M, B> J[3];
        for (int i = 0; i < count; ++i) {
            blocks[i] = t % 11 == 0 && i > 0 ? blocks[0] : pick(rng);  // repeats
            for (int r = 0; r < M; ++r) {
                for (int c = 0; c < B; ++c) J[i](r, c) = g(rng);
            }
        }
        Eigen::Matrix<double, M, M> W;
        W << 2.0, 0.3, 0.3, 1.0;
        const Eigen::Matrix<double, M, 1> r(g(rng), g(rng));
        sys.template Add<M>(blocks, J, count, W, r);
        (t % 2 == 0 ? half_a : half_b).template Add<M>(blocks, J, count, W, r);
        // The dense reference, block by block (a full J^T W J per term is slow under the
        // sanitizers for the 520-unknown systems).
        for (int i = 0; i < count; ++i) {
            const Eigen::Matrix<double, B, M> JtW = J[i].transpose() * W;
            const Eigen::Matrix<double, B, 1> gi = JtW * r;
            for (int u = 0; u < B; ++u) grad(B * blocks[i] + u) += gi(u);
            for (int j = 0; j < count; ++j) {
                const Eigen::Matrix<double, B, B> hij = JtW * J[j];
                for (int u = 0; u < B; ++u) {
                    for (int v = 0; v < B; ++v)
                        H(B * blocks[i] + u, B * blocks[j] + v) += hij(u, v);
                }
            }
        }
    }
    for (int b = 0; b < kBlocks; ++b) {  // a prior keeps every block determined
        sys.AddPrior(static_cast<std::size_t>(b),
                     Eigen::Matrix<double, B, B>::Identity(),
                     Eigen::Matrix<double, B, 1>::Constant(0.5));
        half_b.AddPrior(static_cast<std::size_t>(b),
                        Eigen::Matrix<double, B, B>::Identity(),
                        Eigen::Matrix<double, B, 1>::Constant(0.5));
        H.block(B * b, B * b, B, B) += Eigen::MatrixXd::Identity(B, B);
        grad.segment(B * b, B) += Eigen::VectorXd::Constant(B, 0.5);
    }
    DampedSolver<B> solver(sys);
    ASSERT_EQ(solver.num_unknowns(), static_cast<std::size_t>(B * kBlocks));
    Eigen::VectorXd x;
    ASSERT_TRUE(solver.Solve(0.0, &x));
    const Eigen::VectorXd want = -H.ldlt().solve(grad);
    EXPECT_LT((x - want).norm(), 1e-7 * (1 + want.norm()));
    half_a.Merge(half_b);
    EXPECT_EQ(half_a.num_off_diagonal(), sys.num_off_diagonal());
    DampedSolver<B> merged(half_a);
    Eigen::VectorXd xm;
    ASSERT_TRUE(merged.Solve(0.0, &xm));
    EXPECT_LT((xm - want).norm(), 1e-7 * (1 + want.norm()));
    const Eigen::MatrixXd C = solver.InverseLeadingBlock(B + 1);
    const Eigen::MatrixXd Cd =
        H.ldlt().solve(Eigen::MatrixXd::Identity(B * kBlocks, B + 1)).topRows(B + 1);
    EXPECT_LT((C - Cd).norm(), 1e-7 * Cd.norm());
    // Marginal covariances: diagonal blocks of H^-1 and the blocks to the next block, from
    // batched solves (a batch of 3 blocks leaves a partial last batch), against a dense inverse.
    const Eigen::MatrixXd Hinv = H.inverse();
    std::vector<std::size_t> which;
    for (int b = 0; b < kBlocks; b += 2) which.push_back(static_cast<std::size_t>(b));
    which.push_back(static_cast<std::size_t>(kBlocks - 1));
    std::vector<Eigen::Matrix<double, B, B>> diag, next;
    ASSERT_TRUE(solver.InverseBlocks(which, 3, &diag, &next));
    ASSERT_EQ(diag.size(), which.size());
    for (std::size_t i = 0; i < which.size(); ++i) {
        const auto o = static_cast<Eigen::Index>(B * which[i]);
        const Eigen::MatrixXd d = Hinv.block(o, o, B, B);
        EXPECT_LT((diag[i] - d).norm(), 1e-7 * Hinv.norm()) << "block " << which[i];
        if (which[i] + 1 < static_cast<std::size_t>(kBlocks)) {
            const Eigen::MatrixXd n = Hinv.block(o, o + B, B, B);
            EXPECT_LT((next[i] - n).norm(), 1e-7 * Hinv.norm()) << "block " << which[i];
        } else {
            EXPECT_EQ(next[i].norm(), 0.0);
        }
    }
    EXPECT_FALSE(solver.InverseBlocks({static_cast<std::size_t>(kBlocks)}, 3, &diag, &next));
    const Eigen::MatrixXd R = Eigen::MatrixXd::Random(B * kBlocks, 3);
    EXPECT_LT((solver.SolveMany(R) - Hinv * R).norm(), 1e-7 * Hinv.norm() * R.norm());
    EXPECT_EQ(solver.SolveMany(Eigen::MatrixXd::Ones(B * kBlocks + 1, 2)).size(), 0);
    // Levenberg damping: (H + lambda diag(H)) x = -g, a shorter step.
    const double lambda = 3.0;
    ASSERT_TRUE(solver.Solve(lambda, &x));
    Eigen::MatrixXd A = H;
    A.diagonal() *= 1.0 + lambda;
    EXPECT_LT((x - (-A.ldlt().solve(grad))).norm(), 1e-7 * (1 + want.norm()));
    EXPECT_LT(x.norm(), want.norm());
}

TEST(DampedSolver, ScalarBlocksMatchADenseSolve) {
    CheckAgainstDense<1>(5);
}
TEST(DampedSolver, PoseBlocksMatchADenseSolve) {
    CheckAgainstDense<6>(6);
}
TEST(DampedSolver, LargeSystemsHeldSparselyMatchADenseSolve) {
    CheckAgainstDense<1>(8, 520);
    CheckAgainstDense<6>(9, 86);
}

TEST(DampedSolver, NonFiniteSystemFailsCleanly) {
    BlockSystem<1> sys(2);
    const int b[1] = {0};
    const Eigen::Matrix<double, 1, 1> J[1] = {Eigen::Matrix<double, 1, 1>::Constant(NAN)};
    sys.Add<1>(
        b, J, 1, Eigen::Matrix<double, 1, 1>::Identity(), Eigen::Matrix<double, 1, 1>::Ones());
    DampedSolver<1> solver(sys);
    Eigen::VectorXd x;
    EXPECT_FALSE(solver.Solve(0.0, &x));
    EXPECT_EQ(solver.InverseLeadingBlock(1).size(), 0);
}

TEST(Robust, RobustWeights) {
    EXPECT_DOUBLE_EQ(RobustWeight(RobustKernel::kNone, 10.0, 1.0), 1.0);
    EXPECT_DOUBLE_EQ(RobustWeight(RobustKernel::kHuber, 0.5, 1.0), 1.0);
    EXPECT_DOUBLE_EQ(RobustWeight(RobustKernel::kHuber, 4.0, 1.0), 0.25);
    EXPECT_DOUBLE_EQ(RobustWeight(RobustKernel::kCauchy, 0.0, 2.0), 1.0);
    EXPECT_DOUBLE_EQ(RobustWeight(RobustKernel::kCauchy, 2.0, 2.0), 0.5);
}

// The step guard compares RobustCost; the normal equations use RobustWeight: the weight must be
// rho'(s) / (2 s) of that cost, and the cost continuous and equal to s^2 near zero.
TEST(Robust, RobustCostMatchesItsWeight) {
    for (const auto k : {RobustKernel::kNone, RobustKernel::kHuber, RobustKernel::kCauchy}) {
        for (const double s : {0.3, 0.9, 1.5, 3.0, 10.0}) {
            const double h = 1e-6;
            const double d = (RobustCost(k, s + h, 1.2) - RobustCost(k, s - h, 1.2)) / (2 * h);
            EXPECT_NEAR(d / (2 * s), RobustWeight(k, s, 1.2), 1e-6)
                << static_cast<int>(k) << " " << s;
        }
        EXPECT_NEAR(RobustCost(k, 0.01, 1.2), 1e-4, 1e-8);
        EXPECT_NEAR(RobustCost(k, 1.2 + 1e-9, 1.2), RobustCost(k, 1.2 - 1e-9, 1.2), 1e-6);
    }
}

}  // namespace
}  // namespace pitmap::proc::reg
