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
        : diag_(num_blocks, BlockMatrix::Zero()),
          grad_(num_blocks, BlockVector::Zero()),
          dense_(num_blocks * B <= kDenseUnknowns) {
        if (dense_) {
            dense_off_.assign(num_blocks * num_blocks, BlockMatrix::Zero());
            touched_.assign(num_blocks * num_blocks, 0);
        }
    }

    std::size_t num_blocks() const { return diag_.size(); }

    // Adds J^T W J to H and J^T W r to g for a residual r of M rows that depends on `count`
    // blocks: J[i] = dr / d(block blocks[i]). A block may appear more than once.
    template <int M>
    void Add(const int* blocks,
             const Eigen::Matrix<double, M, B>* J,
             int count,
             const Eigen::Matrix<double, M, M>& W,
             const Eigen::Matrix<double, M, 1>& r) {
        for (int i = 0; i < count; ++i) {
            const Eigen::Matrix<double, B, M> JtW = J[i].transpose() * W;
            const auto bi = static_cast<std::size_t>(blocks[i]);
            grad_[bi] += JtW * r;
            for (int j = 0; j < count; ++j) {
                if (blocks[i] == blocks[j]) {
                    diag_[bi] += JtW * J[j];
                } else if (blocks[i] < blocks[j]) {
                    OffDiagonal(bi, static_cast<std::size_t>(blocks[j])) += JtW * J[j];
                }
            }
        }
    }

    // A Gaussian prior on block b: H_bb += info, g_b += info * (x_b - prior).
    void AddPrior(std::size_t b, const BlockMatrix& info, const BlockVector& x_minus_prior) {
        diag_[b] += info;
        grad_[b] += info * x_minus_prior;
    }

    // Adds m to the diagonal block b and v to the gradient of block b, and m to the upper
    // off-diagonal block (i, j), i < j: a window of another system, block by block.
    void AddDiagonal(std::size_t b, const BlockMatrix& m, const BlockVector& v) {
        diag_[b] += m;
        grad_[b] += v;
    }
    void AddOffDiagonal(std::size_t i, std::size_t j, const BlockMatrix& m) {
        OffDiagonal(i, j) += m;
    }

    // Adds every term of `o` (same block count), e.g. per-thread systems.
    void Merge(const BlockSystem& o) {
        for (std::size_t i = 0; i < diag_.size(); ++i) {
            diag_[i] += o.diag_[i];
            grad_[i] += o.grad_[i];
        }
        o.ForEachOffDiagonal(
            [&](std::size_t i, std::size_t j, const BlockMatrix& m) { OffDiagonal(i, j) += m; });
    }

    const std::vector<BlockMatrix>& diag() const { return diag_; }
    const std::vector<BlockVector>& grad() const { return grad_; }
    // Calls f(i, j, H_ij) for every upper off-diagonal block (i < j) that a term touched.
    template <class F>
    void ForEachOffDiagonal(F&& f) const {
        const std::size_t n = diag_.size();
        if (dense_) {
            for (std::size_t k = 0; k < touched_.size(); ++k) {
                if (touched_[k] != 0) f(k / n, k % n, dense_off_[k]);
            }
            return;
        }
        for (const auto& [key, m] : off_) f(key / n, key % n, m);
    }
    std::size_t num_off_diagonal() const {
        if (!dense_) return off_.size();
        std::size_t c = 0;
        for (const char t : touched_) c += t != 0 ? 1 : 0;
        return c;
    }

private:
    // Systems of up to this many unknowns keep their off-diagonal blocks in a dense array (at
    // most 2 MB) instead of a hash map: the calibration's pair terms touch 16 of its ~100 scalar
    // unknowns, 120 hash lookups each (measured: 1.5 % of the stage's CPU on bejanca). SLAM's
    // thousands of pose blocks stay sparse.
    static constexpr std::size_t kDenseUnknowns = 512;

    BlockMatrix& OffDiagonal(std::size_t i, std::size_t j) {
        const std::size_t key = i * diag_.size() + j;
        if (dense_) {
            touched_[key] = 1;
            return dense_off_[key];
        }
        auto it = off_.find(key);
        if (it == off_.end()) it = off_.emplace(key, BlockMatrix::Zero()).first;
        return it->second;
    }

    std::vector<BlockMatrix> diag_;
    std::vector<BlockVector> grad_;
    bool dense_;
    std::vector<BlockMatrix> dense_off_;  // dense_: n x n, upper part used
    std::vector<char> touched_;           // dense_: which of dense_off_ a term reached
    std::unordered_map<std::uint64_t, BlockMatrix> off_;  // sparse: key i * n + j, i < j
};

template <int B>
class DampedSolver {
public:
    explicit DampedSolver(const BlockSystem<B>& system);
    ~DampedSolver();
    DampedSolver(const DampedSolver&) = delete;
    DampedSolver& operator=(const DampedSolver&) = delete;

    std::size_t num_unknowns() const;
    // The sparse Cholesky factor's size and cost for the ordering CHOLMOD chose (its analysis:
    // nonzeros of L and floating-point operations of one factorisation): how the fill of the
    // normal equations grows with the problem.
    double factor_nonzeros() const;
    double factor_flops() const;
    // Solves (H + lambda diag(H) + 1e-9 I) delta = -g; false if the factorisation fails or the
    // step is not finite. lambda = 0 is the Gauss-Newton step.
    bool Solve(double lambda, Eigen::VectorXd* delta);
    // The leading k x k block of (H + lambda diag(H) + 1e-9 I)^-1 of the last successful Solve
    // (the formal covariance of the first k unknowns when lambda = 0); empty if none.
    Eigen::MatrixXd InverseLeadingBlock(int k);
    // Blocks of A^-1 for the last successful Solve, A = H + lambda diag(H) + 1e-9 I (lambda = 0:
    // the formal covariance of the unknowns): for each block b of `which` (ascending), its
    // diagonal block (A^-1)_bb and the block (A^-1)_{b,b+1} to the next block (zero for the last
    // block). Solved with the factorisation for batch_blocks blocks (B columns each) at a time:
    // the cost is one solve with B * which.size() right-hand sides. False if there is no
    // factorisation or a block is out of range.
    // A^-1 R for the last successful Solve's A (rows of R: the unknowns); empty if there is no
    // factorisation, R has the wrong row count or the result is not finite.
    Eigen::MatrixXd SolveMany(const Eigen::MatrixXd& R);
    bool InverseBlocks(const std::vector<std::size_t>& which,
                       int batch_blocks,
                       std::vector<Eigen::Matrix<double, B, B>>* diag,
                       std::vector<Eigen::Matrix<double, B, B>>* next);

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

extern template class DampedSolver<1>;
extern template class DampedSolver<6>;

}  // namespace pitmap::proc::reg
