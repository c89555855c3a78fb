// SPDX-License-Identifier: MIT
// The semi-rigid stage's windows (processor/slam/windows.cpp, docs/decisions/017): how the
// nodes are cut into cores and windows, and the windowed sweep on a linear system against the
// whole solve.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "processor/slam/internal.hpp"

namespace pitmap::proc::slam::detail {
namespace {

// n nodes, one per slice, dt_s apart.
struct Nodes {
    Input in;
    Param p;
};

Nodes MakeNodes(std::size_t n, double dt_s) {
    Nodes x;
    std::vector<std::size_t> starts(n);
    for (std::size_t k = 0; k < n; ++k) {
        starts[k] = k;
        x.in.t_s.push_back(1000.0 + static_cast<double>(k) * dt_s);
    }
    x.p = MakeParam(std::vector<Pose>(n, Pose::Identity()), starts);
    return x;
}

TEST(SlamWindows, CoresPartitionTheNodesAndWindowsReachPastThem) {
    const Nodes x = MakeNodes(1000, 1.0);  // 999 s
    for (const double shift : {0.0, 0.5}) {
        const std::vector<NodeWindow> w = MakeWindows(x.in, x.p, 200.0, 30.0, shift);
        // floor(999 / 200) = 4 cores of 249.75 s; shifted by half a core: 3 whole cores and
        // two halves at the ends.
        ASSERT_EQ(w.size(), shift == 0.0 ? 4u : 5u);
        std::size_t next = 0;
        for (const NodeWindow& win : w) {
            EXPECT_EQ(win.core_first, next);
            ASSERT_LT(win.core_first, win.core_last);
            next = win.core_last;
            // The nodes within 30 s of the core (1 s apart).
            EXPECT_EQ(win.first, win.core_first >= 30 ? win.core_first - 30 : 0);
            EXPECT_EQ(win.last, std::min<std::size_t>(win.core_last + 30, 1000));
        }
        EXPECT_EQ(next, 1000u);
        if (shift == 0.5) {
            // The shifted set's boundaries are the centres of the other set's cores.
            const std::vector<NodeWindow> u = MakeWindows(x.in, x.p, 200.0, 30.0, 0.0);
            for (std::size_t i = 0; i < u.size(); ++i) {
                const std::size_t centre = (u[i].core_first + u[i].core_last) / 2;
                EXPECT_LE(
                    std::max(w[i + 1].core_first, centre) - std::min(w[i + 1].core_first, centre),
                    1u);
            }
        }
    }
    // Shorter than two windows, or no window length: one window of every node.
    for (const double window_s : {500.0, 0.0}) {
        const std::vector<NodeWindow> w = MakeWindows(x.in, x.p, window_s, 30.0, 0.0);
        ASSERT_EQ(w.size(), 1u);
        EXPECT_EQ(w[0].first, 0u);
        EXPECT_EQ(w[0].core_first, 0u);
        EXPECT_EQ(w[0].last, 1000u);
        EXPECT_EQ(w[0].core_last, 1000u);
    }
}

// A chain of n pose blocks (relative terms between neighbours, a weak prior on each) with
// long links (node k to k + 40 every 7th node), as SLAM's normal equations: banded in time
// with pair links across passes.
reg::BlockSystem<6> ChainSystem(std::size_t n, std::uint32_t seed) {
    std::mt19937 rng(seed);
    std::normal_distribution<double> gauss;
    const auto random = [&] {
        Matrix6d J;
        for (int r = 0; r < 6; ++r) {
            for (int c = 0; c < 6; ++c) J(r, c) = gauss(rng);
        }
        return J;
    };
    const auto residual = [&] {
        Vector6d r;
        for (int c = 0; c < 6; ++c) r(c) = gauss(rng);
        return r;
    };
    reg::BlockSystem<6> sys(n);
    const Matrix6d W = Matrix6d::Identity();
    for (std::size_t k = 0; k < n; ++k) {
        const int one[1] = {static_cast<int>(k)};
        const Matrix6d prior[1] = {0.1 * Matrix6d::Identity()};
        sys.Add<6>(one, prior, 1, W, residual());
        const std::size_t far[2] = {k + 1, k + 40};
        for (const std::size_t j : far) {
            if (j >= n || (j == k + 40 && k % 7 != 0)) continue;
            const int two[2] = {static_cast<int>(k), static_cast<int>(j)};
            const Matrix6d J[2] = {random(), random()};
            sys.Add<6>(two, J, 2, W, residual());
        }
    }
    return sys;
}

// The same blocks with the gradient g + H x: the system of the step from x.
reg::BlockSystem<6> From(const reg::BlockSystem<6>& sys, const Eigen::VectorXd& x) {
    const std::size_t n = sys.num_blocks();
    Eigen::VectorXd g(6 * static_cast<Eigen::Index>(n));
    for (std::size_t k = 0; k < n; ++k) {
        g.segment<6>(6 * static_cast<Eigen::Index>(k)) =
            sys.grad()[k] + (sys.diag()[k] + 1e-9 * Matrix6d::Identity()) *
                                x.segment<6>(6 * static_cast<Eigen::Index>(k));
    }
    reg::BlockSystem<6> out(n);
    sys.ForEachOffDiagonal([&](std::size_t i, std::size_t j, const Matrix6d& m) {
        out.AddOffDiagonal(i, j, m);
        g.segment<6>(6 * static_cast<Eigen::Index>(i)) +=
            m * x.segment<6>(6 * static_cast<Eigen::Index>(j));
        g.segment<6>(6 * static_cast<Eigen::Index>(j)) +=
            m.transpose() * x.segment<6>(6 * static_cast<Eigen::Index>(i));
    });
    for (std::size_t k = 0; k < n; ++k) {
        out.AddDiagonal(k, sys.diag()[k], g.segment<6>(6 * static_cast<Eigen::Index>(k)));
    }
    return out;
}

// The quadratic model 1/2 x^T (H + 1e-9 I) x + g^T x that a solve minimises.
double Model(const reg::BlockSystem<6>& sys, const Eigen::VectorXd& x) {
    const reg::BlockSystem<6> at = From(sys, x);  // gradient g + A x
    double q = 0;
    for (std::size_t k = 0; k < sys.num_blocks(); ++k) {
        const auto o = 6 * static_cast<Eigen::Index>(k);
        q += 0.5 * x.segment<6>(o).dot(at.grad()[k] + sys.grad()[k]);
    }
    return q;
}

TEST(SlamWindows, OneWindowIsTheWholeSolve) {
    const reg::BlockSystem<6> sys = ChainSystem(200, 1);
    reg::DampedSolver<6> whole(sys);
    WindowedSolver one(sys, {});
    EXPECT_EQ(one.num_windows(), 1u);
    for (const double lambda : {0.0, 1e-3}) {
        Eigen::VectorXd a, b;
        ASSERT_TRUE(whole.Solve(lambda, &a));
        ASSERT_TRUE(one.Solve(lambda, &b));
        EXPECT_EQ((a - b).cwiseAbs().maxCoeff(), 0.0);
    }
    EXPECT_EQ(one.factor_nonzeros(), whole.factor_nonzeros());
}

TEST(SlamWindows, SweepsLowerTheModelAndConvergeToTheWholeSolve) {
    const std::size_t n = 400;
    const Nodes x = MakeNodes(n, 1.0);
    const reg::BlockSystem<6> sys = ChainSystem(n, 2);
    Eigen::VectorXd exact;
    reg::DampedSolver<6> whole(sys);
    ASSERT_TRUE(whole.Solve(0.0, &exact));
    const double q_min = Model(sys, exact);
    ASSERT_LT(q_min, 0.0);

    // One sweep is a descent step on the model, short of its minimum (the long links to
    // later windows lag), and its largest window's factor is smaller than the whole one's.
    Eigen::VectorXd step;
    WindowedSolver first(sys, MakeWindows(x.in, x.p, 80.0, 20.0, 0.0));
    ASSERT_EQ(first.num_windows(), 4u);
    ASSERT_TRUE(first.Solve(0.0, &step));
    const double q1 = Model(sys, step);
    EXPECT_LT(q1, 0.5 * q_min);
    EXPECT_GE(q1, q_min - 1e-9 * std::abs(q_min));
    EXPECT_LT(first.factor_nonzeros(), 0.5 * whole.factor_nonzeros());

    Eigen::VectorXd two_level;
    WindowedSolver coarse(
        sys, MakeWindows(x.in, x.p, 80.0, 20.0, 0.0), MakeCoarseSpace(x.in, x.p, 10.0));
    ASSERT_TRUE(coarse.Solve(0.0, &two_level));

    // Sweeps from the current iterate, alternating the cores, reach the whole solve: the
    // restricted multiplicative Schwarz iteration converges on a positive definite system,
    // with or without the coarse level.
    for (const double coarse_s : {0.0, 10.0}) {
        Eigen::VectorXd at = coarse_s > 0 ? two_level : step;
        double q_prev = Model(sys, at);
        for (int sweep = 1; sweep < 30; ++sweep) {
            const reg::BlockSystem<6> from = From(sys, at);
            WindowedSolver ws(from,
                              MakeWindows(x.in, x.p, 80.0, 20.0, sweep % 2 == 0 ? 0.0 : 0.5),
                              MakeCoarseSpace(x.in, x.p, coarse_s));
            Eigen::VectorXd d;
            ASSERT_TRUE(ws.Solve(0.0, &d));
            at += d;
            const double q = Model(sys, at);
            EXPECT_LE(q, q_prev + 1e-9 * std::abs(q_min)) << "sweep " << sweep;
            q_prev = q;
        }
        EXPECT_LT((at - exact).norm(), 1e-6 * exact.norm()) << "coarse " << coarse_s;
    }
}

// The rigid stage's layout (docs/decisions/021): one node per 15 s section over an hour,
// windows of 600 s reaching 120 s past their cores, coarse nodes every 60 s. One window (no
// window length) is the whole solve bit for bit; sweeps from the current iterate, alternating
// the cores, lower the model and reach the whole solve.
TEST(SlamWindows, RigidLayoutOneWindowIsWholeAndSweepsReachIt) {
    const std::size_t n = 240;  // 3 600 s of 15 s sections
    const Nodes x = MakeNodes(n, 15.0);
    const reg::BlockSystem<6> sys = ChainSystem(n, 3);
    reg::DampedSolver<6> whole(sys);
    Eigen::VectorXd exact;
    ASSERT_TRUE(whole.Solve(0.0, &exact));
    const double q_min = Model(sys, exact);

    SlamConfig cfg;
    cfg.section_length_s = 15.0;
    const double coarse_s = WindowCoarseSeconds(SlamStage::kRigid, cfg);
    ASSERT_EQ(coarse_s, 60.0);
    {
        WindowedSolver one(sys,
                           MakeWindows(x.in, x.p, 0.0, cfg.rigid_window_overlap_s, 0.0),
                           MakeCoarseSpace(x.in, x.p, coarse_s));
        ASSERT_EQ(one.num_windows(), 1u);
        Eigen::VectorXd d;
        ASSERT_TRUE(one.Solve(1e-3, &d));
        Eigen::VectorXd e;
        ASSERT_TRUE(whole.Solve(1e-3, &e));
        EXPECT_EQ((d - e).cwiseAbs().maxCoeff(), 0.0);
    }
    Eigen::VectorXd at = Eigen::VectorXd::Zero(6 * static_cast<Eigen::Index>(n));
    double q_prev = 0.0;
    double largest = 0;
    for (int sweep = 0; sweep < 30; ++sweep) {
        const reg::BlockSystem<6> from = From(sys, at);
        WindowedSolver ws(from,
                          MakeWindows(x.in,
                                      x.p,
                                      cfg.rigid_window_s,
                                      cfg.rigid_window_overlap_s,
                                      sweep % 2 == 0 ? 0.0 : 0.5),
                          MakeCoarseSpace(x.in, x.p, coarse_s));
        ASSERT_GE(ws.num_windows(), 5u);  // floor(3 585 s / 600 s) cores, 6 when shifted
        Eigen::VectorXd d;
        ASSERT_TRUE(ws.Solve(0.0, &d));
        largest = std::max(largest, ws.factor_nonzeros());
        at += d;
        const double q = Model(sys, at);
        // The first sweep takes most of the way; the restricted sweeps (each window's result
        // kept on its core only) are not strictly monotone near the minimum: measured rises of
        // at most 30 % of the remaining gap on the shifted sweeps, none on the others.
        if (sweep == 0) {
            EXPECT_LT(q, 0.5 * q_min);
        }
        EXPECT_LE(q, q_prev + 0.5 * (q_prev - q_min) + 1e-9 * std::abs(q_min))
            << "sweep " << sweep << " q - q_prev " << q - q_prev << " q - q_min " << q - q_min;
        q_prev = q;
    }
    EXPECT_LT((at - exact).norm(), 1e-6 * exact.norm());
    EXPECT_LT(largest, 0.5 * whole.factor_nonzeros());
    // The coarse spacing: a tenth of the window unless set, never finer than the sections.
    cfg.rigid_window_coarse_s = 5.0;
    EXPECT_EQ(WindowCoarseSeconds(SlamStage::kRigid, cfg), 15.0);
    cfg.rigid_window_coarse_s = 90.0;
    EXPECT_EQ(WindowCoarseSeconds(SlamStage::kRigid, cfg), 90.0);
    EXPECT_EQ(WindowCoarseSeconds(SlamStage::kSemiRigid, cfg), 60.0);
    cfg.semi_rigid_window_s = 80.0;
    EXPECT_EQ(WindowCoarseSeconds(SlamStage::kSemiRigid, cfg), 15.0);
    cfg.semi_rigid_window_coarse_s = 45.0;
    EXPECT_EQ(WindowCoarseSeconds(SlamStage::kSemiRigid, cfg), 45.0);
}

TEST(SlamWindows, CoarseSpaceInterpolatesBetweenItsNodes) {
    const Nodes x = MakeNodes(101, 0.5);  // 50 s
    const CoarseSpace c = MakeCoarseSpace(x.in, x.p, 15.0);
    ASSERT_EQ(c.size, 5u);  // at 0, 15, 30, 45, 60 s
    for (std::size_t k = 0; k < 101; ++k) {
        const double t = 0.5 * static_cast<double>(k);
        EXPECT_EQ(c.a[k], static_cast<std::uint32_t>(t / 15.0)) << k;
        EXPECT_NEAR(c.w[k], t / 15.0 - std::floor(t / 15.0), 1e-12) << k;
    }
    EXPECT_EQ(MakeCoarseSpace(x.in, x.p, 0.0).size, 0u);
}

TEST(SlamWindows, WindowParamRenumbersTheWindowsNodes) {
    Nodes x = MakeNodes(50, 1.0);
    for (std::size_t k = 0; k < 50; ++k) x.p.tc[k] = Eigen::Vector3d(static_cast<double>(k), 0, 0);
    for (std::size_t s = 0; s < 50; ++s) x.p.k0[s] = x.p.k1[s] = static_cast<int>(s);
    const Param w = WindowParam(x.p, 10, 20);
    ASSERT_EQ(w.num_nodes(), 10u);
    for (std::size_t k = 0; k < 10; ++k) {
        EXPECT_EQ(w.tc[k].x(), static_cast<double>(k + 10));
        EXPECT_EQ(w.anchor[k], static_cast<int>(k + 10));
    }
    for (std::size_t s = 10; s < 20; ++s) {
        Eigen::Matrix3d Ra, Rb;
        Eigen::Vector3d ta, tb;
        SliceCorrection(x.p, s, &Ra, &ta);
        SliceCorrection(w, s, &Rb, &tb);
        EXPECT_EQ(ta, tb);
    }
}

}  // namespace
}  // namespace pitmap::proc::slam::detail
