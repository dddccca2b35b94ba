#include "deform/BlockCholesky.h"

#include <Eigen/Cholesky>
#include <Eigen/OrderingMethods>
#include <Eigen/SparseCore>
#include <algorithm>

namespace splatwarp {

void BlockCholesky3::analyze(int n, const std::vector<std::pair<int, int>>& blocks)
{
    mN = n;
    mBlocks = blocks;
    // Fill-reducing order of the block graph: AMD on a pattern with one entry per block.
    std::vector<Eigen::Triplet<double>> trip;
    trip.reserve(blocks.size());
    for (const auto& b : blocks) trip.emplace_back(b.first, b.second, 1.0);
    Eigen::SparseMatrix<double> pattern(n, n);
    pattern.setFromTriplets(trip.begin(), trip.end());
    Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> order;
    Eigen::AMDOrdering<int>()(pattern, order); // order.indices()[new] = old
    mNewOf.assign(std::size_t(n), 0);
    for (int i = 0; i < n; ++i) mNewOf[std::size_t(order.indices()[i])] = i;

    // Block pattern of L by symbolic elimination on a dense mask (n is a few hundred nodes).
    std::vector<char> mask(std::size_t(n) * std::size_t(n), 0); // mask[i * n + j], i > j
    for (const auto& b : blocks) {
        const int i = mNewOf[std::size_t(b.first)], j = mNewOf[std::size_t(b.second)];
        if (i > j) mask[std::size_t(i) * std::size_t(n) + std::size_t(j)] = 1;
    }
    mColStart.assign(std::size_t(n) + 1, 0);
    mRows.clear();
    std::vector<int> slot(std::size_t(n) * std::size_t(n), -1);
    for (int j = 0; j < n; ++j) {
        const std::size_t begin = mRows.size();
        for (int i = j + 1; i < n; ++i)
            if (mask[std::size_t(i) * std::size_t(n) + std::size_t(j)]) {
                slot[std::size_t(i) * std::size_t(n) + std::size_t(j)] = int(mRows.size());
                mRows.push_back(i);
            }
        for (std::size_t a = begin; a < mRows.size(); ++a)
            for (std::size_t b = begin; b < a; ++b)
                mask[std::size_t(mRows[a]) * std::size_t(n) + std::size_t(mRows[b])] = 1; // fill
        mColStart[std::size_t(j) + 1] = int(mRows.size());
    }
    // Update targets of every column: pair (e1, e2), e2 <= e1, goes to block (row e1, row e2).
    mUpdateStart.assign(std::size_t(n) + 1, 0);
    mUpdateSlot.clear();
    for (int j = 0; j < n; ++j) {
        for (int a = mColStart[std::size_t(j)]; a < mColStart[std::size_t(j) + 1]; ++a)
            for (int b = mColStart[std::size_t(j)]; b <= a; ++b)
                mUpdateSlot.push_back(a == b ? -1 : slot[std::size_t(mRows[std::size_t(a)]) * std::size_t(n) + std::size_t(mRows[std::size_t(b)])]);
        mUpdateStart[std::size_t(j) + 1] = int(mUpdateSlot.size());
    }
    mTarget.resize(blocks.size());
    for (std::size_t b = 0; b < blocks.size(); ++b) {
        const int i = mNewOf[std::size_t(blocks[b].first)], j = mNewOf[std::size_t(blocks[b].second)];
        mTarget[b] = i == j ? -1 : i < j ? -2 : slot[std::size_t(i) * std::size_t(n) + std::size_t(j)];
    }
    mL.assign(mRows.size(), Eigen::Matrix3d::Zero());
    mDiag.assign(std::size_t(n), Eigen::Matrix3d::Zero());
}

bool BlockCholesky3::factorize(const std::vector<Eigen::Matrix3d>& values)
{
    for (Eigen::Matrix3d& m : mL) m.setZero();
    for (std::size_t b = 0; b < mBlocks.size(); ++b) {
        if (mTarget[b] >= 0) mL[std::size_t(mTarget[b])] = values[b];
        else if (mTarget[b] == -1) mDiag[std::size_t(mNewOf[std::size_t(mBlocks[b].first)])] = values[b];
    }
    // Right-looking: finish column j, then subtract its outer products from the later columns.
    for (int j = 0; j < mN; ++j) {
        const Eigen::LLT<Eigen::Matrix3d> llt(mDiag[std::size_t(j)]);
        if (llt.info() != Eigen::Success) return false;
        const Eigen::Matrix3d lInv = llt.matrixL().solve(Eigen::Matrix3d::Identity());
        if (!lInv.allFinite()) return false;
        mDiag[std::size_t(j)] = lInv;
        const int c0 = mColStart[std::size_t(j)], c1 = mColStart[std::size_t(j) + 1];
        for (int a = c0; a < c1; ++a) mL[std::size_t(a)] = (mL[std::size_t(a)] * lInv.transpose()).eval();
        const int* upd = mUpdateSlot.data() + mUpdateStart[std::size_t(j)];
        for (int a = c0; a < c1; ++a) {
            const Eigen::Matrix3d& la = mL[std::size_t(a)];
            for (int b = c0; b <= a; ++b, ++upd) {
                if (*upd < 0) mDiag[std::size_t(mRows[std::size_t(a)])].noalias() -= la * la.transpose();
                else mL[std::size_t(*upd)].noalias() -= la * mL[std::size_t(b)].transpose();
            }
        }
    }
    return true;
}

Eigen::VectorXd BlockCholesky3::solve(const Eigen::VectorXd& b) const
{
    Eigen::VectorXd y(3 * mN);
    for (int i = 0; i < mN; ++i) y.segment<3>(3 * mNewOf[std::size_t(i)]) = b.segment<3>(3 * i);
    for (int j = 0; j < mN; ++j) { // L y = P b
        const Eigen::Vector3d yj = mDiag[std::size_t(j)] * y.segment<3>(3 * j);
        y.segment<3>(3 * j) = yj;
        for (int a = mColStart[std::size_t(j)]; a < mColStart[std::size_t(j) + 1]; ++a)
            y.segment<3>(3 * mRows[std::size_t(a)]).noalias() -= mL[std::size_t(a)] * yj;
    }
    for (int j = mN - 1; j >= 0; --j) { // L^T z = y
        Eigen::Vector3d zj = y.segment<3>(3 * j);
        for (int a = mColStart[std::size_t(j)]; a < mColStart[std::size_t(j) + 1]; ++a)
            zj.noalias() -= mL[std::size_t(a)].transpose() * y.segment<3>(3 * mRows[std::size_t(a)]);
        y.segment<3>(3 * j) = mDiag[std::size_t(j)].transpose() * zj;
    }
    Eigen::VectorXd x(3 * mN);
    for (int i = 0; i < mN; ++i) x.segment<3>(3 * i) = y.segment<3>(3 * mNewOf[std::size_t(i)]);
    return x;
}

} // namespace splatwarp
