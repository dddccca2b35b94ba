#pragma once
/// @file ShRotationMath.h
/// @brief SH rotation as plain data and host/device functions (one source of truth for
///        ShRotation on the CPU and the CUDA kernels): host-computed projection tables, the band
///        matrices of a rotation built from them, and their application to [K,3] coefficients.
#include "core/HostDevice.h"
#include "core/SmallMath.h"
#include "sh/SphericalHarmonics.h"

namespace splatwarp {

/// Directions at which each band is sampled to recover its rotated coefficients.
constexpr int kShRotationDirs = 16;

/// @brief Fixed directions and per-band least-squares pseudo-inverses (band l: (2l+1) x dirs).
///        Plain data: copy it to the GPU as is (constant memory or a device buffer).
struct ShRotationTables {
    Vec3d dirs[kShRotationDirs];
    double pinv[4][7][kShRotationDirs];
};

/// @brief The host tables, computed once (Eigen pseudo-inverse); thread-safe.
const ShRotationTables& shRotationTables();

/// @brief Band matrices D_l = pinv(B_l) * B_l(R^T dirs) for l = 1..degree (degree 0..3, not checked).
SPLATWARP_HOST_DEVICE void buildShBands(const ShRotationTables& t, const Mat3d& r, int degree, ShBands& out)
{
    // f'(d) = f(R^T d): values of the rotated function at dirs are the old basis at R^T dirs.
    const Mat3d rt = r.transposed();
    double rotated[kShRotationDirs][16];
    for (int i = 0; i < kShRotationDirs; ++i) evalShBasis(degree, rt * t.dirs[i], rotated[i]);
    for (int l = 1; l <= degree; ++l) {
        const int n = 2 * l + 1, base = l * l;
        for (int a = 0; a < n; ++a)
            for (int b = 0; b < n; ++b) {
                double s = 0.0;
                for (int i = 0; i < kShRotationDirs; ++i) s += t.pinv[l][a][i] * rotated[i][base + b];
                out.band[l][a * n + b] = s;
            }
    }
}

/// @brief Rotate coefficients [K,3] in place with bands built for at least this degree (not checked).
template <typename T>
SPLATWARP_HOST_DEVICE void applyShBands(const ShBands& bands, int degree, T* coeffs)
{
    for (int l = 1; l <= degree; ++l) {
        const int n = 2 * l + 1, base = l * l;
        const double* d = bands.band[l];
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

/// @brief buildShBands + applyShBands: rotate one coefficient set by R (degree 0 is a no-op).
template <typename T>
SPLATWARP_HOST_DEVICE void rotateSh(const ShRotationTables& t, const Mat3d& r, int degree, T* coeffs)
{
    if (degree <= 0) return;
    ShBands bands;
    buildShBands(t, r, degree, bands);
    applyShBands(bands, degree, coeffs);
}

} // namespace splatwarp
