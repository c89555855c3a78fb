// SPDX-License-Identifier: MIT
// The semi-rigid stage's solve by overlapping windows in time (SlamConfig::semi_rigid_window_s,
// docs/decisions/017). A pit surveyed N times is a graph of the pit's surface times the passes:
// every pass pairs with the passes nearest in time over each cell (decision 015), so a cut
// through the survey in time is one coverage of the pit, and a cut across the pit grows with
// N. A sparse Cholesky factor of the whole survey's normal equations then fills like a
// surface grid whose nodes grow with N: nonzeros about N^2, flops N^3 on bejanca 1x-4x
// (6.2 M, 83 M nonzeros at 1x, 4x), whatever the ordering. Windows of a fixed duration keep
// each factor's size fixed and their number linear in the survey.
#include <algorithm>
#include <cmath>
#include <utility>

#include "processor/slam/internal.hpp"

namespace pitmap::proc::slam::detail {

std::vector<NodeWindow> MakeWindows(
    const Input& in, const Param& p, double window_s, double overlap_s, double shift) {
    const std::size_t n = p.num_nodes();
    const auto whole = [n] { return std::vector<NodeWindow>{{0, n, 0, n}}; };
    if (n == 0 || !(window_s > 0)) return whole();
    const auto t = [&](std::size_t k) { return in.t_s[static_cast<std::size_t>(p.anchor[k])]; };
    const double t0 = t(0), duration = t(n - 1) - t0;
    const auto cores = static_cast<std::size_t>(std::floor(duration / window_s));
    if (cores < 2) return whole();
    const double core_s = duration / static_cast<double>(cores);
    // Core boundaries in time: t0 + (i + shift) core_s, those strictly inside the survey.
    std::vector<double> cuts;
    for (std::size_t i = 0; i <= cores; ++i) {
        const double c = t0 + (static_cast<double>(i) + shift) * core_s;
        if (c > t0 && c < t0 + duration) cuts.push_back(c);
    }
    // The first node at or after time x (after it, when `after`).
    const auto node_at = [&](double x, bool after = false) {
        std::size_t lo = 0, hi = n;
        while (lo < hi) {
            const std::size_t mid = (lo + hi) / 2;
            if (t(mid) < x || (after && t(mid) == x)) {
                lo = mid + 1;
            } else {
                hi = mid;
            }
        }
        return lo;
    };
    std::vector<std::size_t> bounds{0};
    for (const double c : cuts) {
        const std::size_t k = node_at(c);
        if (k > bounds.back() && k < n) bounds.push_back(k);
    }
    bounds.push_back(n);
    if (bounds.size() < 3) return whole();
    std::vector<NodeWindow> out;
    for (std::size_t w = 0; w + 1 < bounds.size(); ++w) {
        NodeWindow win;
        win.core_first = bounds[w];
        win.core_last = bounds[w + 1];
        win.first = node_at(t(win.core_first) - overlap_s);
        win.last = std::max(win.core_last, node_at(t(win.core_last - 1) + overlap_s, true));
        out.push_back(win);
    }
    return out;
}

CoarseSpace MakeCoarseSpace(const Input& in, const Param& p, double coarse_s) {
    CoarseSpace c;
    const std::size_t n = p.num_nodes();
    if (n == 0 || !(coarse_s > 0)) return c;
    const auto t = [&](std::size_t k) { return in.t_s[static_cast<std::size_t>(p.anchor[k])]; };
    const double t0 = t(0);
    c.size = static_cast<std::size_t>(std::ceil((t(n - 1) - t0) / coarse_s)) + 1;
    c.a.resize(n);
    c.w.resize(n);
    for (std::size_t k = 0; k < n; ++k) {
        const double u = (t(k) - t0) / coarse_s;
        const auto a = std::min(static_cast<std::size_t>(std::floor(u)), c.size - 1);
        c.a[k] = static_cast<std::uint32_t>(a);
        c.w[k] = a + 1 < c.size ? u - static_cast<double>(a) : 0.0;
    }
    return c;
}

double WindowCoarseSeconds(SlamStage stage, const SlamConfig& cfg) {
    const bool rigid = stage == SlamStage::kRigid;
    const double set = rigid ? cfg.rigid_window_coarse_s : cfg.semi_rigid_window_coarse_s;
    const double window_s = rigid ? cfg.rigid_window_s : cfg.semi_rigid_window_s;
    return std::max(set > 0 ? set : 0.1 * window_s, cfg.section_length_s);
}

WindowedSolver::WindowedSolver(const reg::BlockSystem<6>& sys,
                               std::vector<NodeWindow> windows,
                               CoarseSpace coarse)
    : sys_(sys), windows_(std::move(windows)), coarse_(std::move(coarse)) {
    const std::size_t n = sys.num_blocks();
    if (windows_.size() <= 1) {
        windows_.assign(1, NodeWindow{0, n, 0, n});
        whole_ = std::make_unique<reg::DampedSolver<6>>(sys);
        factor_nonzeros_ = whole_->factor_nonzeros();
        factor_flops_ = whole_->factor_flops();
        return;
    }
    // Both triangles' links per row node, in compressed rows.
    row_start_.assign(n + 1, 0);
    sys.ForEachOffDiagonal([&](std::size_t i, std::size_t j, const Matrix6d&) {
        ++row_start_[i + 1];
        ++row_start_[j + 1];
    });
    for (std::size_t i = 0; i < n; ++i) row_start_[i + 1] += row_start_[i];
    link_node_.resize(row_start_[n]);
    link_block_.resize(row_start_[n]);
    link_transposed_.resize(row_start_[n]);
    std::vector<std::size_t> fill(row_start_.begin(), row_start_.end() - 1);
    sys.ForEachOffDiagonal([&](std::size_t i, std::size_t j, const Matrix6d& m) {
        const std::size_t a = fill[i]++, b = fill[j]++;
        link_node_[a] = static_cast<std::uint32_t>(j);
        link_block_[a] = &m;
        link_transposed_[a] = 0;
        link_node_[b] = static_cast<std::uint32_t>(i);
        link_block_[b] = &m;
        link_transposed_[b] = 1;
    });
}

bool WindowedSolver::SolveCoarse(double lambda, Eigen::VectorXd* x) {
    const std::size_t n = sys_.num_blocks();
    const auto at = [](std::size_t k) { return static_cast<Eigen::Index>(6 * k); };
    // P^T A P and P^T g, block by block: node k spreads over its two coarse nodes.
    reg::BlockSystem<6> c(coarse_.size);
    const auto spread = [&](std::size_t k, auto&& f) {
        f(coarse_.a[k], 1.0 - coarse_.w[k]);
        if (coarse_.w[k] > 0) f(coarse_.a[k] + 1, coarse_.w[k]);
    };
    // (block (i, j) of A times wi wj) into the coarse block (a, b), upper triangle kept.
    const auto add = [&](std::size_t a, std::size_t b, const Matrix6d& m) {
        if (a < b) {
            c.AddOffDiagonal(a, b, m);
        } else if (b < a) {
            c.AddOffDiagonal(b, a, m.transpose());
        } else {
            c.AddDiagonal(a, 0.5 * (m + m.transpose()), Vector6d::Zero());
        }
    };
    for (std::size_t k = 0; k < n; ++k) {
        Matrix6d d = sys_.diag()[k];
        d.diagonal() = d.diagonal() * (1.0 + lambda) + Vector6d::Constant(1e-9);
        spread(k, [&](std::size_t a, double wa) {
            c.AddDiagonal(a, Matrix6d::Zero(), wa * sys_.grad()[k]);
            spread(k, [&](std::size_t b, double wb) {
                if (a <= b) add(a, b, wa * wb * d);
            });
        });
    }
    sys_.ForEachOffDiagonal([&](std::size_t i, std::size_t j, const Matrix6d& m) {
        spread(i, [&](std::size_t a, double wa) {
            spread(j, [&](std::size_t b, double wb) {
                // A_ij and A_ji = A_ij^T both land in the coarse system.
                if (a == b) {
                    add(a, a, wa * wb * (m + m.transpose()));
                } else {
                    add(a, b, wa * wb * m);
                }
            });
        });
    });
    reg::DampedSolver<6> ne(c);  // already damped: solved with lambda 0
    Eigen::VectorXd X;
    if (!ne.Solve(0.0, &X)) return false;
    x->setZero(at(n));
    for (std::size_t k = 0; k < n; ++k) {
        spread(k,
               [&](std::size_t a, double wa) { x->segment<6>(at(k)) += wa * X.segment<6>(at(a)); });
    }
    return true;
}

bool WindowedSolver::Solve(double lambda, Eigen::VectorXd* delta) {
    if (whole_) return whole_->Solve(lambda, delta);
    const std::size_t n = sys_.num_blocks();
    delta->setZero(static_cast<Eigen::Index>(6 * n));
    factor_nonzeros_ = factor_flops_ = 0;
    const auto at = [](std::size_t k) { return static_cast<Eigen::Index>(6 * k); };
    if (coarse_.size > 1 && !SolveCoarse(lambda, delta)) return false;
    for (const NodeWindow& w : windows_) {
        // A_WW x_W = -(g_W + A_WO x_O): the damping touches diagonal blocks only, so A_WO is
        // H_WO; x_O is zero where no core has been solved yet in this sweep.
        reg::BlockSystem<6> sub(w.last - w.first);
        for (std::size_t i = w.first; i < w.last; ++i) {
            Vector6d g = sys_.grad()[i];
            for (std::size_t l = row_start_[i]; l < row_start_[i + 1]; ++l) {
                const std::size_t j = link_node_[l];
                const Matrix6d& m = *link_block_[l];
                if (j < w.first || j >= w.last) {
                    const Vector6d xj = delta->segment<6>(at(j));
                    g += link_transposed_[l] != 0 ? Vector6d(m.transpose() * xj) : Vector6d(m * xj);
                } else if (j > i) {
                    sub.AddOffDiagonal(i - w.first, j - w.first, m);
                }
            }
            sub.AddDiagonal(i - w.first, sys_.diag()[i], g);
        }
        reg::DampedSolver<6> ne(sub);
        factor_nonzeros_ = std::max(factor_nonzeros_, ne.factor_nonzeros());
        factor_flops_ += ne.factor_flops();
        Eigen::VectorXd x;
        if (!ne.Solve(lambda, &x)) return false;
        for (std::size_t k = w.core_first; k < w.core_last; ++k) {
            delta->segment<6>(at(k)) = x.segment<6>(at(k - w.first));
        }
    }
    return delta->allFinite();
}

Param WindowParam(const Param& p, std::size_t first, std::size_t last) {
    Param w;
    w.base = p.base;
    w.pivot = p.pivot;
    w.alpha = p.alpha;
    w.k0.resize(p.k0.size());
    w.k1.resize(p.k1.size());
    const auto local = [&](int k) {
        const auto u = static_cast<std::size_t>(k);
        return u >= first && u < last ? static_cast<int>(u - first) : 0;
    };
    for (std::size_t s = 0; s < p.k0.size(); ++s) {
        w.k0[s] = local(p.k0[s]);
        w.k1[s] = local(p.k1[s]);
    }
    const auto f = static_cast<std::ptrdiff_t>(first), l = static_cast<std::ptrdiff_t>(last);
    w.anchor.assign(p.anchor.begin() + f, p.anchor.begin() + l);
    w.Rc.assign(p.Rc.begin() + f, p.Rc.begin() + l);
    w.tc.assign(p.tc.begin() + f, p.tc.begin() + l);
    return w;
}

}  // namespace pitmap::proc::slam::detail
