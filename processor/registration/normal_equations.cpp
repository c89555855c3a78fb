// SPDX-License-Identifier: MIT
#include "processor/registration/normal_equations.hpp"

#include <Eigen/CholmodSupport>
#include <Eigen/SparseCore>
#include <algorithm>

namespace pitmap::proc::reg {

template <int B>
struct DampedSolver<B>::Impl {
    Eigen::SparseMatrix<double> H;  // upper triangle
    Eigen::VectorXd rhs, diag;
    Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>, Eigen::Upper> llt;
    bool factorised = false;
    double factor_nonzeros = 0, factor_flops = 0;  // CHOLMOD's analysis (lnz, fl)
};

template <int B>
DampedSolver<B>::DampedSolver(const BlockSystem<B>& system) : impl_(std::make_unique<Impl>()) {
    const std::size_t n = system.num_blocks();
    const auto& diag = system.diag();
    const auto& grad = system.grad();
    std::vector<Eigen::Triplet<double>> trip;
    trip.reserve(n * static_cast<std::size_t>(B * (B + 1) / 2) +
                 system.num_off_diagonal() * static_cast<std::size_t>(B * B));
    impl_->rhs.resize(static_cast<Eigen::Index>(B * n));
    for (std::size_t i = 0; i < n; ++i) {
        const auto o = static_cast<int>(B * i);
        for (int r = 0; r < B; ++r) {
            for (int c = r; c < B; ++c) trip.emplace_back(o + r, o + c, diag[i](r, c));
        }
        impl_->rhs.template segment<B>(o) = -grad[i];
    }
    system.ForEachOffDiagonal([&](std::size_t bi, std::size_t bj, const auto& m) {
        const auto i = static_cast<int>(bi), j = static_cast<int>(bj);
        for (int r = 0; r < B; ++r) {
            for (int c = 0; c < B; ++c) trip.emplace_back(B * i + r, B * j + c, m(r, c));
        }
    });
    const auto dim = static_cast<Eigen::Index>(B * n);
    impl_->H.resize(dim, dim);
    impl_->H.setFromTriplets(trip.begin(), trip.end());
    impl_->H.makeCompressed();
    impl_->diag = impl_->H.diagonal();
    impl_->llt.analyzePattern(impl_->H);
    impl_->factor_nonzeros = impl_->llt.cholmod().lnz;
    impl_->factor_flops = impl_->llt.cholmod().fl;
}

template <int B>
DampedSolver<B>::~DampedSolver() = default;

template <int B>
std::size_t DampedSolver<B>::num_unknowns() const {
    return static_cast<std::size_t>(impl_->rhs.size());
}

template <int B>
double DampedSolver<B>::factor_nonzeros() const {
    return impl_->factor_nonzeros;
}

template <int B>
double DampedSolver<B>::factor_flops() const {
    return impl_->factor_flops;
}

template <int B>
bool DampedSolver<B>::Solve(double lambda, Eigen::VectorXd* delta) {
    Impl& s = *impl_;
    s.factorised = false;
    Eigen::SparseMatrix<double> A = s.H;
    A.diagonal() = s.diag * (1.0 + lambda) + Eigen::VectorXd::Constant(s.diag.size(), 1e-9);
    s.llt.factorize(A);
    if (s.llt.info() != Eigen::Success) return false;
    *delta = s.llt.solve(s.rhs);
    s.factorised = s.llt.info() == Eigen::Success && delta->allFinite();
    return s.factorised;
}

template <int B>
Eigen::MatrixXd DampedSolver<B>::InverseLeadingBlock(int k) {
    Impl& s = *impl_;
    if (!s.factorised || k <= 0 || k > s.rhs.size()) return {};
    Eigen::MatrixXd E = Eigen::MatrixXd::Zero(s.rhs.size(), k);
    for (int i = 0; i < k; ++i) E(i, i) = 1.0;
    const Eigen::MatrixXd X = s.llt.solve(E);
    return X.topRows(k);
}

template <int B>
Eigen::MatrixXd DampedSolver<B>::SolveMany(const Eigen::MatrixXd& R) {
    Impl& s = *impl_;
    if (!s.factorised || R.rows() != s.rhs.size()) return {};
    Eigen::MatrixXd X = s.llt.solve(R);
    if (s.llt.info() != Eigen::Success || !X.allFinite()) return {};
    return X;
}

template <int B>
bool DampedSolver<B>::InverseBlocks(const std::vector<std::size_t>& which,
                                    int batch_blocks,
                                    std::vector<Eigen::Matrix<double, B, B>>* diag,
                                    std::vector<Eigen::Matrix<double, B, B>>* next) {
    Impl& s = *impl_;
    const auto dim = s.rhs.size();
    const auto num_blocks = static_cast<std::size_t>(dim / B);
    if (!s.factorised) return false;
    for (const std::size_t b : which) {
        if (b >= num_blocks) return false;
    }
    diag->assign(which.size(), Eigen::Matrix<double, B, B>::Zero());
    next->assign(which.size(), Eigen::Matrix<double, B, B>::Zero());
    const std::size_t batch = static_cast<std::size_t>(std::max(1, batch_blocks));
    for (std::size_t first = 0; first < which.size(); first += batch) {
        const std::size_t count = std::min(batch, which.size() - first);
        Eigen::MatrixXd E = Eigen::MatrixXd::Zero(dim, static_cast<Eigen::Index>(B * count));
        for (std::size_t i = 0; i < count; ++i) {
            const auto o = static_cast<Eigen::Index>(B * which[first + i]);
            const auto c = static_cast<Eigen::Index>(B * i);
            for (int u = 0; u < B; ++u) E(o + u, c + u) = 1.0;
        }
        const Eigen::MatrixXd X = s.llt.solve(E);
        if (s.llt.info() != Eigen::Success || !X.allFinite()) return false;
        for (std::size_t i = 0; i < count; ++i) {
            const std::size_t b = which[first + i];
            const auto o = static_cast<Eigen::Index>(B * b);
            const auto c = static_cast<Eigen::Index>(B * i);
            // X's columns are (A^-1)_{:,b}; A^-1 is symmetric, so rows b+1 give (A^-1)_{b+1,b}.
            (*diag)[first + i] = X.block(o, c, B, B);
            if (b + 1 < num_blocks) (*next)[first + i] = X.block(o + B, c, B, B).transpose();
        }
    }
    return true;
}

template class DampedSolver<1>;
template class DampedSolver<6>;

}  // namespace pitmap::proc::reg
