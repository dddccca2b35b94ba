#pragma once
/// @file PreparedGaussian.h
/// @brief A Gaussian reduced to what a feature evaluation needs (centre, inverse filtered
///        covariance, alpha, cutoff radius, exact AABB), computed once per evaluation so the
///        inner loop over (point, Gaussian) pairs is a few multiply-adds and one exp.
#include <algorithm>
#include <cmath>

#include "core/FastExp.h"
#include "core/GaussianCloud.h"
#include "core/HostDevice.h"
#include "core/SmallMath.h"
#include "field/GaussianMath.h"

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

/// @brief One Gaussian prepared for feature evaluation (float on the CPU path; double in
///        gradient tests).
template <typename T>
struct BasicPreparedGaussian {
    Vec3<T> mean;
    /// L^-1 (lower triangular, row-major 00, 10, 11, 20, 21, 22) of the Cholesky factor cov = L L^T:
    /// d^T cov^-1 d = |L^-1 d|^2, a sum of squares, which keeps float accuracy for elongated
    /// Gaussians where the expanded quadratic form cancels badly.
    T invL[6] = {0, 0, 0, 0, 0, 0};
    T alpha = 0;      ///< activated opacity
    T radius2 = -1;   ///< squared Mahalanobis radius where alpha*G = cutoff, padded (< 0: never contributes)
    Vec3<T> halfExtent = Vec3<T>(-1, -1, -1); ///< exact AABB half extent of the cutoff ellipsoid, padded

    /// @brief Convert from another precision.
    template <typename U>
    SPLATWARP_HOST_DEVICE static BasicPreparedGaussian from(const BasicPreparedGaussian<U>& o)
    {
        BasicPreparedGaussian g;
        g.mean = Vec3<T>(o.mean);
        for (int k = 0; k < 6; ++k) g.invL[k] = T(o.invL[k]);
        g.alpha = T(o.alpha);
        g.radius2 = T(o.radius2);
        g.halfExtent = Vec3<T>(o.halfExtent);
        return g;
    }
    /// @brief u = L^-1 d (so d^T cov^-1 d = |u|^2).
    SPLATWARP_HOST_DEVICE Vec3<T> whiten(const Vec3<T>& d) const
    {
        return {invL[0] * d.x, invL[1] * d.x + invL[2] * d.y, invL[3] * d.x + invL[4] * d.y + invL[5] * d.z};
    }
    /// @brief cov^-1 d = L^-T u.
    SPLATWARP_HOST_DEVICE Vec3<T> applyInverse(const Vec3<T>& u) const
    {
        return {invL[0] * u.x + invL[1] * u.y + invL[3] * u.z, invL[2] * u.y + invL[4] * u.z, invL[5] * u.z};
    }
    /// @brief alpha*G at offset d = x - mean when it reaches the cutoff, else 0. The AABB and
    ///        radius tests only prune; the decision is alpha*G >= cutoff. When ad is given and
    ///        the pair counts, *ad = cov^-1 d (for the backward pass).
    SPLATWARP_HOST_DEVICE T weight(const Vec3<T>& d, T cutoff, Vec3<T>* ad = nullptr) const
    {
        if (std::fabs(d.x) > halfExtent.x || std::fabs(d.y) > halfExtent.y || std::fabs(d.z) > halfExtent.z) return T(0);
        const Vec3<T> u = whiten(d);
        const T q = dot(u, u);
        if (!(q <= radius2)) return T(0);
        const T w = alpha * expOf(T(-0.5) * q);
        if (!(w >= cutoff)) return T(0);
        if (ad) *ad = applyInverse(u);
        return w;
    }
};
using PreparedGaussian = BasicPreparedGaussian<float>;

/// @brief The pruning AABB of a prepared Gaussian, mean -/+ halfExtent (lo > hi: it never
///        contributes), as the feature bins (CPU and GPU) use it.
SPLATWARP_HOST_DEVICE void preparedBox(const PreparedGaussian& g, float* lo, float* hi)
{
    for (int k = 0; k < 3; ++k) {
        lo[k] = g.mean[k] - g.halfExtent[k];
        hi[k] = g.mean[k] + g.halfExtent[k];
    }
}

/// Relative padding of the pruning bounds, so rounding never prunes a pair whose alpha*G is
/// (just) above the cutoff.
constexpr double kPrunePad = 1e-3;

/// @brief Prepare a Gaussian from its centre, filtered covariance and alpha.
template <typename T>
SPLATWARP_HOST_DEVICE BasicPreparedGaussian<T> prepareGaussian(const Vec3<T>& mean, const Mat3<T>& cov, T alpha, T cutoff)
{
    BasicPreparedGaussian<T> g;
    g.mean = mean;
    g.alpha = alpha;
    // Cholesky cov = L L^T, then invert the triangular L.
    const T l00 = std::sqrt(cov.m[0][0]);
    const T l10 = cov.m[1][0] / l00, l20 = cov.m[2][0] / l00;
    const T l11 = std::sqrt(std::max(cov.m[1][1] - l10 * l10, T(0)));
    const T l21 = (cov.m[2][1] - l20 * l10) / l11;
    const T l22 = std::sqrt(std::max(cov.m[2][2] - l20 * l20 - l21 * l21, T(0)));
    const T i00 = 1 / l00, i11 = 1 / l11, i22 = 1 / l22;
    const T i10 = -l10 * i00 / l11;
    const T i21 = -l21 * i11 / l22;
    const T i20 = -(l20 * i00 + l21 * i10) / l22;
    g.invL[0] = i00; g.invL[1] = i10; g.invL[2] = i11;
    g.invL[3] = i20; g.invL[4] = i21; g.invL[5] = i22;
    const T r = extentRadius(alpha, cutoff);
    if (r > 0) {
        g.radius2 = r * r * T(1 + kPrunePad) + T(kPrunePad);
        g.halfExtent = ellipsoidHalfExtent(cov, r * T(1 + kPrunePad));
    }
    return g;
}

/// @brief Prepare Gaussian i of a cloud with an isotropic filter variance (0 = none).
inline PreparedGaussian prepareGaussian(const GaussianCloud& cloud, std::size_t i, double filterVariance, double cutoff)
{
    const Mat3d filter = Mat3d::identity() * filterVariance;
    const Mat3d cov = filteredCovariance(Quatd{cloud.rotations[4 * i], cloud.rotations[4 * i + 1],
                                               cloud.rotations[4 * i + 2], cloud.rotations[4 * i + 3]},
                                         Vec3d(cloud.scale(i)), filter);
    return PreparedGaussian::from(prepareGaussian(Vec3d(cloud.mean(i)), cov, sigmoid(double(cloud.opacities[i])), cutoff));
}

} // namespace splatwarp
