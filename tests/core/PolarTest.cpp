// Host/device Jacobi eigen-decomposition and polar decomposition (core/Polar.h) against
// Eigen's SVD in double (the reference).
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <random>

#include "core/Polar.h"

using namespace splatwarp;

namespace {

Eigen::Matrix3d toEigen(const Mat3d& m)
{
    Eigen::Matrix3d e;
    for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) e(a, b) = m.m[a][b];
    return e;
}

/// Reference polar decomposition: Eigen SVD, smallest singular direction flipped when
/// det(U V^T) < 0.
void referencePolar(const Mat3d& m, Eigen::Matrix3d& r, Eigen::Matrix3d& s)
{
    const Eigen::JacobiSVD<Eigen::Matrix3d> svd(toEigen(m), Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Matrix3d u = svd.matrixU();
    const Eigen::Matrix3d v = svd.matrixV();
    Eigen::Vector3d sv = svd.singularValues();
    if ((u * v.transpose()).determinant() < 0.0) {
        u.col(2) *= -1.0;
        sv(2) = -sv(2);
    }
    r = u * v.transpose();
    s = v * sv.asDiagonal() * v.transpose();
}

double maxAbs(const Eigen::Matrix3d& a) { return a.cwiseAbs().maxCoeff(); }

/// Random M = rotation * stretch with singular values in [lo, hi], det sign as asked.
Mat3d randomMatrix(std::mt19937& rng, double lo, double hi, bool negative)
{
    std::uniform_real_distribution<double> u(-1.0, 1.0), sv(lo, hi);
    Eigen::Matrix3d a;
    for (int i = 0; i < 9; ++i) a(i / 3, i % 3) = u(rng);
    const Eigen::HouseholderQR<Eigen::Matrix3d> qr1(a);
    for (int i = 0; i < 9; ++i) a(i / 3, i % 3) = u(rng);
    const Eigen::HouseholderQR<Eigen::Matrix3d> qr2(a);
    const Eigen::Vector3d d(sv(rng), sv(rng), (negative ? -1.0 : 1.0) * sv(rng));
    Eigen::Matrix3d q1 = qr1.householderQ(), q2 = qr2.householderQ();
    if (q1.determinant() < 0) q1.col(0) *= -1.0;
    if (q2.determinant() < 0) q2.col(0) *= -1.0;
    const Eigen::Matrix3d m = q1 * d.asDiagonal() * q2.transpose();
    Mat3d out;
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) out.m[r][c] = m(r, c);
    return out;
}

} // namespace

TEST(Polar, SymmetricEigenDecomposes)
{
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-2.0, 2.0);
    double worst = 0;
    for (int t = 0; t < 500; ++t) {
        Mat3d a;
        for (int i = 0; i < 3; ++i)
            for (int j = i; j < 3; ++j) a.m[i][j] = a.m[j][i] = u(rng);
        if (t % 50 == 0) a = Mat3d::identity() * 2.0; // repeated eigenvalues
        if (t % 50 == 1) a.m[0][1] = a.m[1][0] = a.m[0][2] = a.m[2][0] = 0.0; // partly diagonal
        Vec3d lambda;
        Mat3d v;
        symmetricEigen3(a, lambda, v);
        EXPECT_GE(lambda[0], lambda[1]);
        EXPECT_GE(lambda[1], lambda[2]);
        EXPECT_NEAR(v.determinant(), 1.0, 1e-12);
        const Eigen::Matrix3d ev = toEigen(v);
        const Eigen::Matrix3d back = ev * Eigen::Vector3d(lambda.x, lambda.y, lambda.z).asDiagonal() * ev.transpose();
        worst = std::max({worst, maxAbs(back - toEigen(a)), maxAbs(ev.transpose() * ev - Eigen::Matrix3d::Identity())});
        const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> ref(toEigen(a));
        for (int k = 0; k < 3; ++k) EXPECT_NEAR(lambda[k], ref.eigenvalues()(2 - k), 1e-12 * (1 + std::fabs(lambda[k])));
    }
    std::printf("  worst reconstruction/orthogonality error %.3g\n", worst);
    EXPECT_LT(worst, 1e-13); // measured 4e-15 (500 matrices, seed 7)
}

TEST(Polar, PolarMatchesEigenReference)
{
    std::mt19937 rng(11);
    double worstR = 0, worstS = 0, worstM = 0;
    for (int t = 0; t < 400; ++t) {
        const bool negative = t % 4 == 3;
        // Singular values from near-rigid (0.8..1.25) to strongly anisotropic (0.01..10).
        const Mat3d m = t % 2 ? randomMatrix(rng, 0.8, 1.25, negative) : randomMatrix(rng, 0.01, 10.0, negative);
        Mat3d r, s;
        polarDecomposition(m, r, s);
        Eigen::Matrix3d rr, rs;
        referencePolar(m, rr, rs);
        const Eigen::Matrix3d er = toEigen(r), es = toEigen(s);
        EXPECT_NEAR(er.determinant(), 1.0, 1e-12);
        EXPECT_LT(maxAbs(er.transpose() * er - Eigen::Matrix3d::Identity()), 1e-12);
        EXPECT_LT(maxAbs(es - es.transpose()), 1e-12);
        worstM = std::max(worstM, maxAbs(er * es - toEigen(m)) / maxAbs(toEigen(m)));
        worstR = std::max(worstR, maxAbs(er - rr));
        worstS = std::max(worstS, maxAbs(es - rs) / maxAbs(rs));
    }
    std::printf("  worst |RS - M|/|M| %.3g, |R - R_ref| %.3g, |S - S_ref|/|S| %.3g\n", worstM, worstR, worstS);
    // Measured (400 matrices, seed 11, condition numbers up to 1e3): 6.8e-15, 6.8e-14, 4.8e-14.
    EXPECT_LT(worstM, 1e-13);
    EXPECT_LT(worstR, 1e-12);
    EXPECT_LT(worstS, 1e-12);
}

TEST(Polar, DegenerateInputsStayFinite)
{
    for (const Mat3d& m : {Mat3d(), Mat3d::identity(), Mat3d::identity() * -1.0}) {
        Mat3d r, s;
        polarDecomposition(m, r, s);
        EXPECT_NEAR(r.determinant(), 1.0, 1e-12);
        for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b) EXPECT_TRUE(std::isfinite(s.m[a][b]));
        const Eigen::Matrix3d back = toEigen(r) * toEigen(s);
        EXPECT_LT(maxAbs(back - toEigen(m)), 1e-12);
    }
    Mat3d rankOne; // projection onto x scaled by 2
    rankOne.m[0][0] = 2.0;
    Mat3d r, s;
    polarDecomposition(rankOne, r, s);
    EXPECT_NEAR(r.determinant(), 1.0, 1e-12);
    EXPECT_LT(maxAbs(toEigen(r) * toEigen(s) - toEigen(rankOne)), 1e-12);
}
