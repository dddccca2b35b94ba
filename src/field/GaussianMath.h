#pragma once
/// @file GaussianMath.h
/// @brief Per-Gaussian maths shared by every path (CPU features, Stage II, CUDA, rendering):
///        covariance, the opacity-aware extent and the cutoff test. One source of truth.
#include "core/HostDevice.h"
#include "core/SmallMath.h"

namespace splatwarp {

/// Default contribution cutoff: a pair (point, Gaussian) counts only where alpha*G >= 1/255,
/// the smallest contribution an 8-bit image can show.
constexpr float kDefaultCutoff = 1.0f / 255.0f;

/// Default low-pass filter strength lambda_lpf: variance lambda * spacing^2 (times F_k F_k^T in
/// Stage II) is added to every covariance; 0.2 is Mip-Splatting's 3D filter value.
constexpr float kDefaultLambdaLpf = 0.2f;

/// @brief Covariance R S S^T R^T from a (raw, normalised on use) quaternion and standard deviations.
template <typename T>
SPLATWARP_HOST_DEVICE Mat3<T> gaussianCovariance(const Quat<T>& q, const Vec3<T>& scale)
{
    const Mat3<T> r = quatToMatrix(q);
    Mat3<T> c;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
            T s = 0;
            for (int k = 0; k < 3; ++k) s += r.m[i][k] * scale[k] * scale[k] * r.m[j][k];
            c.m[i][j] = s;
        }
    return c;
}

/// @brief Mahalanobis radius r with alpha*exp(-r^2/2) = cutoff: sqrt(2 ln(alpha/cutoff)),
///        0 when alpha <= cutoff (the Gaussian never contributes).
template <typename T>
SPLATWARP_HOST_DEVICE T extentRadius(T alpha, T cutoff)
{
    return alpha > cutoff ? std::sqrt(T(2) * std::log(alpha / cutoff)) : T(0);
}

/// @brief Half extent of the exact axis-aligned box of the ellipsoid x^T cov^-1 x <= r^2:
///        r * sqrt(cov_aa) per axis.
template <typename T>
SPLATWARP_HOST_DEVICE Vec3<T> ellipsoidHalfExtent(const Mat3<T>& cov, T radius)
{
    return {radius * std::sqrt(cov.m[0][0]), radius * std::sqrt(cov.m[1][1]), radius * std::sqrt(cov.m[2][2])};
}

} // namespace splatwarp
