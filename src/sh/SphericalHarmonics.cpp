#include "sh/SphericalHarmonics.h"

#include <Eigen/Dense>
#include <cmath>

#include "core/Error.h"

namespace splatwarp {

namespace {

// Each band's functions span a rotation-invariant space, so the rotated function is again in
// that band and its coefficients follow exactly from its values at a few directions. We use a
// fixed, well-spread set of directions and a least-squares pseudo-inverse per band, computed
// once: D_l = pinv(B_l) * B_l(R^T dirs).
constexpr int kDirs = 16;

struct ShProjector {
    Vec3d dirs[kDirs];
    double pinv[4][7][kDirs]; ///< band l: (2l+1) x kDirs

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
            Eigen::MatrixXd b(kDirs, 2 * l + 1);
            double basis[16];
            for (int i = 0; i < kDirs; ++i) {
                evalShBasis(3, dirs[i], basis);
                for (int m = 0; m < 2 * l + 1; ++m) b(i, m) = basis[l * l + m];
            }
            const Eigen::MatrixXd p = b.completeOrthogonalDecomposition().pseudoInverse();
            for (int m = 0; m < 2 * l + 1; ++m)
                for (int i = 0; i < kDirs; ++i) pinv[l][m][i] = p(m, i);
        }
    }
};

const ShProjector& projector()
{
    static const ShProjector p;
    return p;
}

} // namespace

ShRotation::ShRotation(const Mat3d& r, int degree) : mDegree(degree)
{
    if (degree < 0 || degree > 3) throw InputError(msg("SH degree ", degree, " is outside 0..3"));
    if (degree == 0) return;
    const ShProjector& p = projector();
    // f'(d) = f(R^T d): values of the rotated function at dirs are the old basis at R^T dirs.
    const Mat3d rt = r.transposed();
    double rotated[kDirs][16];
    for (int i = 0; i < kDirs; ++i) evalShBasis(degree, rt * p.dirs[i], rotated[i]);
    for (int l = 1; l <= degree; ++l) {
        const int n = 2 * l + 1, base = l * l;
        for (int a = 0; a < n; ++a)
            for (int b = 0; b < n; ++b) {
                double s = 0.0;
                for (int i = 0; i < kDirs; ++i) s += p.pinv[l][a][i] * rotated[i][base + b];
                mBand[l][a * n + b] = s;
            }
    }
}

template <typename T>
void ShRotation::applyImpl(int degree, T* coeffs) const
{
    if (degree > mDegree) throw Error(msg("ShRotation built for degree ", mDegree, " applied to degree ", degree));
    for (int l = 1; l <= degree; ++l) {
        const int n = 2 * l + 1, base = l * l;
        const double* d = mBand[l];
        double in[7][3];
        for (int m = 0; m < n; ++m)
            for (int c = 0; c < 3; ++c) in[m][c] = double(coeffs[3 * (base + m) + c]);
        for (int i = 0; i < n; ++i)
            for (int c = 0; c < 3; ++c) {
                double s = 0.0;
                for (int j = 0; j < n; ++j) s += d[i * n + j] * in[j][c];
                coeffs[3 * (base + i) + c] = T(s);
            }
    }
}

void ShRotation::apply(int degree, float* coeffs) const { applyImpl(degree, coeffs); }
void ShRotation::apply(int degree, double* coeffs) const { applyImpl(degree, coeffs); }

void rotateCloudSh(GaussianCloud& cloud, const Mat3d& r)
{
    if (cloud.shDegree == 0) return;
    const ShRotation rot(r, cloud.shDegree);
    for (std::size_t i = 0; i < cloud.size(); ++i) rot.apply(cloud.shDegree, cloud.shOf(i));
}

} // namespace splatwarp
