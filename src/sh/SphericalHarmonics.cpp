#include "sh/SphericalHarmonics.h"

#include <Eigen/Dense>
#include <cmath>

#include "core/Error.h"
#include "sh/ShRotationMath.h"

namespace splatwarp {

namespace {

// Each band's functions span a rotation-invariant space, so the rotated function is again in
// that band and its coefficients follow exactly from its values at a few directions. We use a
// fixed, well-spread set of directions and a least-squares pseudo-inverse per band, computed
// once: D_l = pinv(B_l) * B_l(R^T dirs) (buildShBands()).
ShRotationTables makeTables()
{
    ShRotationTables t;
    constexpr int kDirs = kShRotationDirs;
    // Fibonacci sphere: well spread, deterministic, no direction on a symmetry axis.
    const double golden = M_PI * (3.0 - std::sqrt(5.0));
    for (int i = 0; i < kDirs; ++i) {
        const double z = 1.0 - (i + 0.5) * 2.0 / kDirs;
        const double r = std::sqrt(1.0 - z * z);
        t.dirs[i] = Vec3d(r * std::cos(golden * i + 0.3), r * std::sin(golden * i + 0.3), z);
    }
    for (int l = 0; l < 4; ++l)
        for (int m = 0; m < 7; ++m)
            for (int i = 0; i < kDirs; ++i) t.pinv[l][m][i] = 0.0; // unused entries defined (copied to the GPU)
    for (int l = 1; l <= 3; ++l) {
        Eigen::MatrixXd b(kDirs, 2 * l + 1);
        double basis[16];
        for (int i = 0; i < kDirs; ++i) {
            evalShBasis(3, t.dirs[i], basis);
            for (int m = 0; m < 2 * l + 1; ++m) b(i, m) = basis[l * l + m];
        }
        const Eigen::MatrixXd p = b.completeOrthogonalDecomposition().pseudoInverse();
        for (int m = 0; m < 2 * l + 1; ++m)
            for (int i = 0; i < kDirs; ++i) t.pinv[l][m][i] = p(m, i);
    }
    return t;
}

} // namespace

const ShRotationTables& shRotationTables()
{
    static const ShRotationTables t = makeTables();
    return t;
}

ShRotation::ShRotation(const Mat3d& r, int degree) : mDegree(degree)
{
    if (degree < 0 || degree > 3) throw InputError(msg("SH degree ", degree, " is outside 0..3"));
    if (degree == 0) return;
    buildShBands(shRotationTables(), r, degree, mBands);
}

template <typename T>
void ShRotation::applyImpl(int degree, T* coeffs) const
{
    if (degree > mDegree) throw Error(msg("ShRotation built for degree ", mDegree, " applied to degree ", degree));
    applyShBands(mBands, degree, coeffs);
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
