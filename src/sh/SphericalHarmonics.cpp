#include "sh/SphericalHarmonics.h"

#include <Eigen/Dense>
#include <cmath>

namespace splatwarp {

namespace {

// Each band's functions span a rotation-invariant space, so the rotated function is again in
// that band and its coefficients follow exactly from values at a few directions. We use a
// fixed, well-spread set of directions and a least-squares pseudo-inverse per band, computed
// once: D_l = pinv(B_l) * B_l(R^T dirs).
constexpr int kDirs = 24;

struct ShProjector {
    Vec3d dirs[kDirs];
    Eigen::MatrixXd pinv[4]; // band l: (2l+1) x kDirs

    ShProjector()
    {
        // Fibonacci sphere: well spread, deterministic, no direction on a symmetry axis.
        const double golden = M_PI * (3.0 - std::sqrt(5.0));
        for (int i = 0; i < kDirs; ++i) {
            const double z = 1.0 - (i + 0.5) * 2.0 / kDirs;
            const double r = std::sqrt(1.0 - z * z);
            dirs[i] = Vec3d(r * std::cos(golden * i + 0.3), r * std::sin(golden * i + 0.3), z);
        }
        for (int l = 1; l <= 3; ++l) {
            Eigen::MatrixXd b = basisMatrix(l, nullptr);
            pinv[l] = b.completeOrthogonalDecomposition().pseudoInverse();
        }
    }

    /// Rows: directions (optionally rotated by R^T), columns: band-l basis functions.
    Eigen::MatrixXd basisMatrix(int l, const Mat3d* rt) const
    {
        Eigen::MatrixXd b(kDirs, 2 * l + 1);
        double basis[16];
        for (int i = 0; i < kDirs; ++i) {
            const Vec3d d = rt ? (*rt) * dirs[i] : dirs[i];
            evalShBasis(3, d, basis);
            for (int m = 0; m < 2 * l + 1; ++m) b(i, m) = basis[l * l + m];
        }
        return b;
    }
};

const ShProjector& projector()
{
    static const ShProjector p;
    return p;
}

} // namespace

ShRotation::ShRotation(const Mat3d& r)
{
    const ShProjector& p = projector();
    const Mat3d rt = r.transposed();
    // f'(d) = f(R^T d): values of the rotated function at dirs are the old basis at R^T dirs.
    for (int l = 1; l <= 3; ++l) {
        const Eigen::MatrixXd d = p.pinv[l] * p.basisMatrix(l, &rt);
        for (int i = 0; i < 2 * l + 1; ++i)
            for (int j = 0; j < 2 * l + 1; ++j) {
                if (l == 1) mD1[i][j] = d(i, j);
                if (l == 2) mD2[i][j] = d(i, j);
                if (l == 3) mD3[i][j] = d(i, j);
            }
    }
}

double ShRotation::band(int l, int i, int j) const
{
    return l == 1 ? mD1[i][j] : (l == 2 ? mD2[i][j] : mD3[i][j]);
}

template <typename T>
void ShRotation::applyImpl(int degree, T* coeffs) const
{
    for (int l = 1; l <= degree; ++l) {
        const int n = 2 * l + 1, base = l * l;
        double in[7][3];
        for (int m = 0; m < n; ++m)
            for (int c = 0; c < 3; ++c) in[m][c] = double(coeffs[3 * (base + m) + c]);
        for (int i = 0; i < n; ++i)
            for (int c = 0; c < 3; ++c) {
                double s = 0.0;
                for (int j = 0; j < n; ++j) s += band(l, i, j) * in[j][c];
                coeffs[3 * (base + i) + c] = T(s);
            }
    }
}

void ShRotation::apply(int degree, float* coeffs) const { applyImpl(degree, coeffs); }
void ShRotation::apply(int degree, double* coeffs) const { applyImpl(degree, coeffs); }

void rotateCloudSh(GaussianCloud& cloud, const Mat3d& r)
{
    if (cloud.shDegree == 0) return;
    const ShRotation rot(r);
    for (std::size_t i = 0; i < cloud.size(); ++i) rot.apply(cloud.shDegree, cloud.shOf(i));
}

} // namespace splatwarp
