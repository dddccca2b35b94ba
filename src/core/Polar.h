#pragma once
/// @file Polar.h
/// @brief 3x3 symmetric eigen-decomposition (cyclic Jacobi) and polar decomposition M = R S,
///        host/device, no Eigen: one implementation for Stage I per Gaussian, the target SH
///        rotation of warped samples, held-out evaluation, and the GPU.
#include "core/HostDevice.h"
#include "core/SmallMath.h"

namespace splatwarp {

/// @brief A = V diag(lambda) V^T for a symmetric A: eigenvalues descending, V orthonormal
///        with det V = +1 (columns are the eigenvectors).
/// @param sweeps  Jacobi sweeps at most (each zeroes the 3 off-diagonal entries once); 3x3
///                matrices converge to rounding in < 10, the cap only bounds NaN input
template <typename T>
SPLATWARP_HOST_DEVICE void symmetricEigen3(const Mat3<T>& a, Vec3<T>& lambda, Mat3<T>& v, int sweeps = 32)
{
    Mat3<T> m = a;
    v = Mat3<T>::identity();
    for (int sweep = 0; sweep < sweeps; ++sweep) {
        const T off = m.m[0][1] * m.m[0][1] + m.m[0][2] * m.m[0][2] + m.m[1][2] * m.m[1][2];
        const T diag = m.m[0][0] * m.m[0][0] + m.m[1][1] * m.m[1][1] + m.m[2][2] * m.m[2][2];
        if (!(off > T(1e-30) * diag) || off == T(0)) break; // converged (relative to the matrix scale)
        for (int pq = 0; pq < 3; ++pq) {
            const int p = pq == 2 ? 1 : 0, q = pq == 0 ? 1 : 2;
            const T apq = m.m[p][q];
            if (apq == T(0)) continue;
            // Rotation in the (p, q) plane that zeroes m_pq (Numerical Recipes' stable form).
            const T theta = (m.m[q][q] - m.m[p][p]) / (T(2) * apq);
            const T t = (theta >= T(0) ? T(1) : T(-1)) / (std::fabs(theta) + std::sqrt(theta * theta + T(1)));
            const T c = T(1) / std::sqrt(t * t + T(1)), s = t * c;
            for (int k = 0; k < 3; ++k) { // columns: M J, V J
                const T mkp = m.m[k][p], mkq = m.m[k][q];
                m.m[k][p] = c * mkp - s * mkq;
                m.m[k][q] = s * mkp + c * mkq;
                const T vkp = v.m[k][p], vkq = v.m[k][q];
                v.m[k][p] = c * vkp - s * vkq;
                v.m[k][q] = s * vkp + c * vkq;
            }
            for (int k = 0; k < 3; ++k) { // rows: J^T (M J)
                const T mpk = m.m[p][k], mqk = m.m[q][k];
                m.m[p][k] = c * mpk - s * mqk;
                m.m[q][k] = s * mpk + c * mqk;
            }
            m.m[p][q] = m.m[q][p] = T(0); // exactly zero by construction; drop the rounding
        }
    }
    lambda = Vec3<T>(m.m[0][0], m.m[1][1], m.m[2][2]);
    // Sort descending (three compare-swaps), moving the eigenvector columns along.
    auto swapColumns = [&](int i, int j) {
        const T l = lambda[i];
        lambda[i] = lambda[j];
        lambda[j] = l;
        for (int k = 0; k < 3; ++k) {
            const T x = v.m[k][i];
            v.m[k][i] = v.m[k][j];
            v.m[k][j] = x;
        }
    };
    if (lambda[0] < lambda[1]) swapColumns(0, 1);
    if (lambda[1] < lambda[2]) swapColumns(1, 2);
    if (lambda[0] < lambda[1]) swapColumns(0, 1);
    if (v.determinant() < T(0))
        for (int k = 0; k < 3; ++k) v.m[k][2] = -v.m[k][2];
}

/// @brief Polar decomposition M = R S with R a proper rotation (det +1) and S symmetric, from
///        the SVD M = U Sigma V^T (V, Sigma^2 from the eigen-decomposition of M^T M). When
///        det M < 0 the smallest singular direction is flipped: S then has one negative
///        eigenvalue, -sigma_min.
template <typename T>
SPLATWARP_HOST_DEVICE void polarDecomposition(const Mat3<T>& m, Mat3<T>& r, Mat3<T>& s)
{
    Vec3<T> lambda;
    Mat3<T> v;
    symmetricEigen3(m.transposed() * m, lambda, v);
    Vec3<T> sigma;
    for (int k = 0; k < 3; ++k) sigma[k] = std::sqrt(lambda[k] > T(0) ? lambda[k] : T(0));
    const Vec3<T> v0(v.m[0][0], v.m[1][0], v.m[2][0]), v1(v.m[0][1], v.m[1][1], v.m[2][1]),
        v2(v.m[0][2], v.m[1][2], v.m[2][2]);
    // U: u0 = M v0 / |.|, u1 = M v1 orthogonalised against u0, u2 = u0 x u1 (so det U = +1).
    auto unitOrthogonal = [](const Vec3<T>& a) { // some unit vector orthogonal to unit a
        const Vec3<T> axis = std::fabs(a.x) < T(0.6) ? Vec3<T>(1, 0, 0) : Vec3<T>(0, 1, 0);
        const Vec3<T> c = cross(a, axis);
        return c / length(c);
    };
    const Vec3<T> mv0 = m * v0;
    const T n0 = length(mv0);
    const Vec3<T> u0 = n0 > T(0) ? mv0 / n0 : Vec3<T>(1, 0, 0);
    Vec3<T> mv1 = m * v1;
    mv1 -= u0 * dot(u0, mv1);
    const T n1 = length(mv1);
    // Relative threshold: below it M is (numerically) rank one and u1 is arbitrary.
    const Vec3<T> u1 = n1 > T(1e-12) * (n0 > T(0) ? n0 : T(1)) ? mv1 / n1 : unitOrthogonal(u0);
    const Vec3<T> u2 = cross(u0, u1);
    // M v2 = sigma2 u2 when det M >= 0, -sigma2 u2 otherwise (U is forced proper).
    const T sign = dot(u2, m * v2) < T(0) ? T(-1) : T(1);
    const T d[3] = {sigma.x, sigma.y, sign * sigma.z};
    for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) {
            r.m[a][b] = u0[a] * v0[b] + u1[a] * v1[b] + u2[a] * v2[b];
            s.m[a][b] = d[0] * v0[a] * v0[b] + d[1] * v1[a] * v1[b] + d[2] * v2[a] * v2[b];
        }
}

/// @brief The rotation R of polarDecomposition().
template <typename T>
SPLATWARP_HOST_DEVICE Mat3<T> polarRotation(const Mat3<T>& m)
{
    Mat3<T> r, s;
    polarDecomposition(m, r, s);
    return r;
}

/// @brief Polar rotation of a matrix close to a rotation (the ED energy keeps the
/// node matrices near-orthonormal): Newton's iteration X <- (X + X^-T) / 2 converges
/// quadratically in a few steps, far cheaper than the Jacobi SVD. Returns false (caller falls back
/// to polarDecomposition()) when det M <= 0 or it does not converge, so the result is the same
/// polar rotation up to rounding (of T: the editor's preview runs it in float).
template <typename T>
SPLATWARP_HOST_DEVICE bool polarRotationNewton(const Mat3<T>& m, Mat3<T>& r)
{
    constexpr int kMaxIterations = 12;
    // |X_k+1 - X_k|_F: the next error is ~kStep^2, below the rounding of T.
    constexpr T kStep = sizeof(T) == sizeof(double) ? T(1e-9) : T(1e-4);
    Mat3<T> x = m;
    for (int it = 0; it < kMaxIterations; ++it) {
        const T det = x.determinant();
        if (!(det > T(0))) return false;
        // X^-T = cofactor(X) / det.
        Mat3<T> cof;
        cof.m[0][0] = x.m[1][1] * x.m[2][2] - x.m[1][2] * x.m[2][1];
        cof.m[0][1] = x.m[1][2] * x.m[2][0] - x.m[1][0] * x.m[2][2];
        cof.m[0][2] = x.m[1][0] * x.m[2][1] - x.m[1][1] * x.m[2][0];
        cof.m[1][0] = x.m[0][2] * x.m[2][1] - x.m[0][1] * x.m[2][2];
        cof.m[1][1] = x.m[0][0] * x.m[2][2] - x.m[0][2] * x.m[2][0];
        cof.m[1][2] = x.m[0][1] * x.m[2][0] - x.m[0][0] * x.m[2][1];
        cof.m[2][0] = x.m[0][1] * x.m[1][2] - x.m[0][2] * x.m[1][1];
        cof.m[2][1] = x.m[0][2] * x.m[1][0] - x.m[0][0] * x.m[1][2];
        cof.m[2][2] = x.m[0][0] * x.m[1][1] - x.m[0][1] * x.m[1][0];
        // Scaling by det^-1/3 (Higham) speeds up matrices far from orthogonal; near det 1 it
        // gains nothing and the cube root would dominate the iteration.
        const T g = std::fabs(det - T(1)) > T(0.25) ? std::cbrt(T(1) / det) : T(1), h = T(0.5) / (g * det);
        T change = T(0);
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) {
                const T next = T(0.5) * g * x.m[i][j] + h * cof.m[i][j];
                change += (next - x.m[i][j]) * (next - x.m[i][j]);
                x.m[i][j] = next;
            }
        if (change <= kStep * kStep) {
            r = x;
            return true;
        }
    }
    return false;
}

/// @brief polarRotation() of a deformation gradient: Newton's iteration first (cheap near a
///        rotation, which ED deformation gradients are), the Jacobi route otherwise.
SPLATWARP_HOST_DEVICE Mat3d polarRotationFast(const Mat3d& m)
{
    Mat3d r;
    return polarRotationNewton(m, r) ? r : polarRotation(m);
}

/// @brief Largest singular value of a row-major 3x3 (a cell's deformation gradient F: its largest
///        stretch), the square root of F^T F's largest eigenvalue.
SPLATWARP_HOST_DEVICE double largestSingularValue(const float* f)
{
    const Mat3d m = Mat3d::fromRowMajor(f);
    Vec3d lambda;
    Mat3d v;
    symmetricEigen3(m.transposed() * m, lambda, v);
    return std::sqrt(lambda.x > 0 ? lambda.x : 0.0);
}

} // namespace splatwarp
