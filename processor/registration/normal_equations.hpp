// SPDX-License-Identifier: MIT
// Gauss-Newton normal equations H delta = -g in blocks of B unknowns (B = 6 for a pose
// correction, 1 for scalar unknowns), accumulated from residual terms that each depend on a
// few blocks, and the damped solver on them: Levenberg's (H + lambda diag(H)) delta = -g by a
// sparse supernodal Cholesky factorisation (CHOLMOD). The sparsity pattern is analysed once per
// system; each damping retry only refactorises. Calibration (a few scalar unknowns) and SLAM
// (thousands of pose blocks) solve through this one module.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <unordered_map>
#include <vector>

namespace pitmap::proc::reg {

template <int B>
class BlockSystem {
public:
    using BlockMatrix = Eigen::Matrix<double, B, B>;
    using BlockVector = Eigen::Matrix<double, B, 1>;

    explicit BlockSystem(std::size_t num_blocks = 0)
        : diag_(num_blocks, BlockMatrix::Zero()), grad_(num_blocks, BlockVector::Zero()) {}

    std::size_t num_blocks() const { return diag_.size(); }

    // Adds J^T W J to H and J^T W r to g for a residual r of M rows that depends on `count`
    // blocks: J[i] = dr / d(block blocks[i]). A block may appear more than once.
    template <int M>
    void Add(const int* blocks,
             const Eigen::Matrix<double, M, B>* J,
             int count,
             const Eigen::Matrix<double, M, M>& W,
             const Eigen::Matrix<double, M, 1>& r) {
        const std::size_t n = diag_.size();
        for (int i = 0; i < count; ++i) {
            const Eigen::Matrix<double, B, M> JtW = J[i].transpose() * W;
            const auto bi = static_cast<std::size_t>(blocks[i]);
            grad_[bi] += JtW * r;
            for (int j = 0; j < count; ++j) {
                if (blocks[i] == blocks[j]) {
                    diag_[bi] += JtW * J[j];
                } else if (blocks[i] < blocks[j]) {
                    const std::uint64_t key =
                        static_cast<std::uint64_t>(bi) * n + static_cast<std::uint64_t>(blocks[j]);
                    auto it = off_.find(key);
                    if (it == off_.end()) it = off_.emplace(key, BlockMatrix::Zero()).first;
                    it->second += JtW * J[j];
                }
            }
        }
    }

    // A Gaussian prior on block b: H_bb += info, g_b += info * (x_b - prior).
    void AddPrior(std::size_t b, const BlockMatrix& info, const BlockVector& x_minus_prior) {
        diag_[b] += info;
        grad_[b] += info * x_minus_prior;
    }

    // Adds every term of `o` (same block count), e.g. per-thread systems.
    void Merge(const BlockSystem& o) {
        for (std::size_t i = 0; i < diag_.size(); ++i) {
            diag_[i] += o.diag_[i];
            grad_[i] += o.grad_[i];
        }
        for (const auto& [key, m] : o.off_) {
            auto it = off_.find(key);
            if (it == off_.end())
                off_.emplace(key, m);
            else
                it->second += m;
        }
    }

    const std::vector<BlockMatrix>& diag() const { return diag_; }
    const std::vector<BlockVector>& grad() const { return grad_; }
    // Upper off-diagonal blocks, key i * num_blocks + j with i < j.
    const std::unordered_map<std::uint64_t, BlockMatrix>& off_diagonal() const { return off_; }

private:
    std::vector<BlockMatrix> diag_;
    std::vector<BlockVector> grad_;
    std::unordered_map<std::uint64_t, BlockMatrix> off_;
};

template <int B>
class DampedSolver {
public:
    explicit DampedSolver(const BlockSystem<B>& system);
    ~DampedSolver();
    DampedSolver(const DampedSolver&) = delete;
    DampedSolver& operator=(const DampedSolver&) = delete;

    std::size_t num_unknowns() const;
    // Solves (H + lambda diag(H) + 1e-9 I) delta = -g; false if the factorisation fails or the
    // step is not finite. lambda = 0 is the Gauss-Newton step.
    bool Solve(double lambda, Eigen::VectorXd* delta);
    // The leading k x k block of (H + lambda diag(H) + 1e-9 I)^-1 of the last successful Solve
    // (the formal covariance of the first k unknowns when lambda = 0); empty if none.
    Eigen::MatrixXd InverseLeadingBlock(int k);

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

extern template class DampedSolver<1>;
extern template class DampedSolver<6>;

}  // namespace pitmap::proc::reg
