#pragma once
/// @file PreparedGaussian.h
/// @brief A Gaussian reduced to what a feature evaluation needs (centre, inverse filtered
///        covariance, alpha, cutoff radius, exact AABB), computed once per evaluation so the
///        inner loop over (point, Gaussian) pairs is a few multiply-adds and one exp.
#include <algorithm>
#include <cmath>

#include "core/GaussianCloud.h"
#include "core/HostDevice.h"
#include "core/SmallMath.h"
#include "field/GaussianKernel.h"

namespace splatwarp {

/// Smallest variance kept along a Gaussian axis, relative to its largest one: flat (GaMeS-style)
/// Gaussians have one scale ~0, and the clamp keeps the covariance invertible in double.
constexpr double kMinRelativeVariance = 1e-12;

/// @brief Per-axis variances s_k^2, clamped so the covariance stays invertible.
template <typename T>
SPLATWARP_HOST_DEVICE Vec3<T> clampedVariances(const Vec3<T>& scale)
{
    Vec3<T> v(scale.x * scale.x, scale.y * scale.y, scale.z * scale.z);
    const T floorV = std::max(std::max(v.x, std::max(v.y, v.z)) * T(kMinRelativeVariance), T(1e-30));
    for (int a = 0; a < 3; ++a) v[a] = std::max(v[a], floorV);
    return v;
}

/// @brief Filtered covariance R diag(v) R^T + filter (v = clamped variances).
template <typename T>
SPLATWARP_HOST_DEVICE Mat3<T> filteredCovariance(const Quat<T>& q, const Vec3<T>& scale, const Mat3<T>& filter)
{
    const Vec3<T> v = clampedVariances(scale);
    const Vec3<T> s(std::sqrt(v.x), std::sqrt(v.y), std::sqrt(v.z));
    return gaussianCovariance(q, s) + filter;
}

/// @brief The float kernel of one Gaussian for feature evaluation.
struct PreparedGaussian {
    Vec3f mean;
    /// L^-1 (lower triangular, row-major 00, 10, 11, 20, 21, 22) of the Cholesky factor cov = L L^T:
    /// d^T cov^-1 d = |L^-1 d|^2, a sum of squares, which keeps float accuracy for elongated
    /// Gaussians where the expanded quadratic form cancels badly.
    float invL[6] = {0, 0, 0, 0, 0, 0};
    float alpha = 0.0f;                ///< activated opacity
    float radius2 = 0.0f;              ///< squared Mahalanobis radius where alpha*G = cutoff (0: never contributes)
    Vec3f halfExtent;                  ///< exact AABB half extent of the cutoff ellipsoid (slightly padded)

    /// @brief Quadratic form d^T inv d.
    SPLATWARP_HOST_DEVICE float mahalanobis2(const Vec3f& d) const
    {
        const float a = invL[0] * d.x;
        const float b = invL[1] * d.x + invL[2] * d.y;
        const float c = invL[3] * d.x + invL[4] * d.y + invL[5] * d.z;
        return a * a + b * b + c * c;
    }
    /// @brief alpha*G at offset d = x - mean when it reaches the cutoff, else 0. The AABB and
    ///        radius tests only prune; the decision is alpha*G >= cutoff.
    SPLATWARP_HOST_DEVICE float weight(const Vec3f& d, float cutoff) const
    {
        if (std::fabs(d.x) > halfExtent.x || std::fabs(d.y) > halfExtent.y || std::fabs(d.z) > halfExtent.z) return 0.0f;
        const float q = mahalanobis2(d);
        if (!(q <= radius2)) return 0.0f;
        const float w = alpha * std::exp(-0.5f * q);
        return w >= cutoff ? w : 0.0f;
    }
};

/// Relative padding of the pruning bounds, so float rounding never prunes a pair whose
/// alpha*G is (just) above the cutoff.
constexpr double kPrunePad = 1e-3;

/// @brief Prepare a Gaussian from its centre, filtered covariance (double) and alpha.
inline PreparedGaussian prepareGaussian(const Vec3f& mean, const Mat3d& cov, double alpha, double cutoff)
{
    PreparedGaussian g;
    g.mean = mean;
    g.alpha = float(alpha);
    // Cholesky cov = L L^T, then invert the triangular L.
    const double l00 = std::sqrt(cov.m[0][0]);
    const double l10 = cov.m[1][0] / l00, l20 = cov.m[2][0] / l00;
    const double l11 = std::sqrt(std::max(cov.m[1][1] - l10 * l10, 0.0));
    const double l21 = (cov.m[2][1] - l20 * l10) / l11;
    const double l22 = std::sqrt(std::max(cov.m[2][2] - l20 * l20 - l21 * l21, 0.0));
    const double i00 = 1 / l00, i11 = 1 / l11, i22 = 1 / l22;
    const double i10 = -l10 * i00 / l11;
    const double i21 = -l21 * i11 / l22;
    const double i20 = -(l20 * i00 + l21 * i10) / l22;
    g.invL[0] = float(i00); g.invL[1] = float(i10); g.invL[2] = float(i11);
    g.invL[3] = float(i20); g.invL[4] = float(i21); g.invL[5] = float(i22);
    const double r = extentRadius(alpha, cutoff);
    g.radius2 = r > 0 ? float(r * r * (1 + kPrunePad) + kPrunePad) : -1.0f;
    const Vec3d h = ellipsoidHalfExtent(cov, r * (1 + kPrunePad));
    g.halfExtent = Vec3f(h);
    if (r <= 0) g.halfExtent = Vec3f(-1, -1, -1);
    return g;
}

/// @brief Prepare Gaussian i of a cloud with an isotropic filter variance (0 = none).
inline PreparedGaussian prepareGaussian(const GaussianCloud& cloud, std::size_t i, double filterVariance, double cutoff)
{
    const Mat3d filter = Mat3d::identity() * filterVariance;
    const Mat3d cov = filteredCovariance(Quatd{cloud.rotations[4 * i], cloud.rotations[4 * i + 1],
                                               cloud.rotations[4 * i + 2], cloud.rotations[4 * i + 3]},
                                         Vec3d(cloud.scale(i)), filter);
    return prepareGaussian(cloud.mean(i), cov, double(cloud.alpha(i)), cutoff);
}

} // namespace splatwarp
