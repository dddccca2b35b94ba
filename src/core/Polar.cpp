#include "core/Polar.h"

#include <Eigen/LU>
#include <Eigen/SVD>

namespace splatwarp {

// GCC reports Eigen's fixed-size JacobiSVD singular values as maybe-uninitialized (a false positive).
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
void polarDecomposition(const Mat3d& m, Mat3d& r, Mat3d& s)
{
    Eigen::Matrix3d em;
    for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) em(a, b) = m[a][b];
    const Eigen::JacobiSVD<Eigen::Matrix3d> svd(em, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Matrix3d u = svd.matrixU();
    const Eigen::Matrix3d v = svd.matrixV();
    Eigen::Matrix3d es = v * svd.singularValues().asDiagonal() * v.transpose();
    if ((u * v.transpose()).determinant() < 0.0) { // Eigen sorts singular values: the last is the smallest
        u.col(2) *= -1.0;
        es -= (2.0 * svd.singularValues()(2)) * v.col(2) * v.col(2).transpose();
    }
    const Eigen::Matrix3d er = u * v.transpose();
    for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) {
            r[a][b] = er(a, b);
            s[a][b] = es(a, b);
        }
}
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif

Mat3d polarRotation(const Mat3d& m)
{
    Mat3d r, s;
    polarDecomposition(m, r, s);
    return r;
}

} // namespace splatwarp
