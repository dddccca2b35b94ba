#pragma once
/// @file BlockCholesky.h
/// @brief Sparse Cholesky factorisation L L^T of a symmetric positive definite matrix made of 3x3
///        blocks (the Schur-reduced ED system: 3 translation unknowns per node). Working on whole
///        blocks with fixed-size arithmetic instead of scalar entries makes each numeric
///        factorisation several times cheaper than a scalar simplicial one for the same fill.
#include <Eigen/Core>
#include <utility>
#include <vector>

namespace splatwarp {

/// @brief Block-sparse L L^T: analyse the block pattern once, factorise per new values, solve.
class BlockCholesky3 {
public:
    /// @brief Symbolic analysis: fill-reducing ordering (AMD on the block graph) and the block
    ///        pattern of L.
    /// @param n       block rows (the matrix is 3n x 3n)
    /// @param blocks  nonzero blocks (row, col) of the full symmetric matrix: both (a, b) and
    ///                (b, a) for a != b, each once; the diagonal blocks must be present
    void analyze(int n, const std::vector<std::pair<int, int>>& blocks);

    /// @brief Numeric factorisation. values[b] is the 3x3 block blocks[b] of analyze().
    /// @return false when the matrix is not (numerically) positive definite
    bool factorize(const std::vector<Eigen::Matrix3d>& values);

    /// @brief Solve A x = b (3n) with the last successful factorisation.
    Eigen::VectorXd solve(const Eigen::VectorXd& b) const;

private:
    int mN = 0;
    std::vector<int> mNewOf;                      // [n] position of block row i in the elimination order
    std::vector<std::pair<int, int>> mBlocks;     // pattern of analyze(), original indices
    std::vector<int> mTarget;                     // [blocks] slot in mL, -1: diagonal, -2: upper (skipped)
    std::vector<int> mColStart;                   // [n+1] start of column j's rows in mRows / mL
    std::vector<int> mRows;                       // rows i > j of L's column j (elimination order), sorted
    std::vector<int> mUpdateSlot;                 // per pair (e1 >= e2) of column j: slot of (row e1, row e2)
    std::vector<int> mUpdateStart;                // [n+1] start of column j's pairs in mUpdateSlot
    std::vector<Eigen::Matrix3d> mL;              // off-diagonal blocks L_ij
    std::vector<Eigen::Matrix3d> mDiag;           // diagonal blocks (A_jj, then inverse of L_jj)
};

} // namespace splatwarp
