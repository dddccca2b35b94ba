#pragma once
/// @file StageTwoParams.h
/// @brief The one packed parameter layout of Stage II (CPU and CUDA solvers): per moving
///        Gaussian mean 3, raw rotation quaternion 4, log-scale 3, logit opacity 1, then the SH
///        coefficients (stride floats), and the Adam update on it. Host/device.
#include <cmath>
#include <cstddef>

#include "core/GaussianCloud.h"
#include "core/HostDevice.h"
#include "stage2/PairGradients.h"
#include "stage2/StageTwoOptions.h"

namespace splatwarp {

/// Offsets of the parameter groups in a packed row.
constexpr int kParamMean = 0, kParamRotation = 3, kParamLogScale = 7, kParamLogit = 10, kParamSh = 11;

/// @brief Floats per packed row at an SH stride.
SPLATWARP_HOST_DEVICE int packedParamCount(int stride) { return kParamSh + stride; }

/// @brief The raw parameters (SH excluded) of a packed row, in double.
SPLATWARP_HOST_DEVICE GaussianParams<double> unpackParams(const float* p) // p: [PER_G]
{
    GaussianParams<double> g;
    g.mean = Vec3d(p[kParamMean], p[kParamMean + 1], p[kParamMean + 2]);
    g.rotation = Quatd{p[kParamRotation], p[kParamRotation + 1], p[kParamRotation + 2], p[kParamRotation + 3]};
    g.logScale = Vec3d(p[kParamLogScale], p[kParamLogScale + 1], p[kParamLogScale + 2]);
    g.logit = p[kParamLogit];
    return g;
}

/// @brief Write a packed row's gradient from the per-Gaussian gradients.
template <typename T>
SPLATWARP_HOST_DEVICE void packGradient(const GaussianParamGrad<T>& g, float* out) // out: [PER_G] (SH left alone)
{
    for (int a = 0; a < 3; ++a) out[kParamMean + a] = float(g.mean[a]);
    out[kParamRotation] = float(g.rotation.w);
    out[kParamRotation + 1] = float(g.rotation.x);
    out[kParamRotation + 2] = float(g.rotation.y);
    out[kParamRotation + 3] = float(g.rotation.z);
    for (int a = 0; a < 3; ++a) out[kParamLogScale + a] = float(g.logScale[a]);
    out[kParamLogit] = float(g.logit);
}

/// @brief Learning rates of one step; the position rate changes per iteration.
struct StepRates {
    float position, rotation, logScale, opacity, sh;

    /// @brief The rate of the parameter at offset c of a packed row.
    SPLATWARP_HOST_DEVICE float of(int c) const
    {
        return c < kParamRotation ? position
                                  : (c < kParamLogScale ? rotation
                                                        : (c < kParamLogit ? logScale : (c == kParamLogit ? opacity : sh)));
    }
};

/// @brief Bias corrections of Adam step t (1-based).
struct AdamStep {
    float beta1, beta2, epsilon;
    double corr1, corr2;

    static AdamStep at(const StageTwoOptions& o, int t)
    {
        return {o.beta1, o.beta2, o.epsilon, 1.0 - std::pow(double(o.beta1), t), 1.0 - std::pow(double(o.beta2), t)};
    }
    /// @brief One Adam update of a parameter with gradient g (float moments, double step).
    SPLATWARP_HOST_DEVICE void update(float& param, float& m, float& v, float g, float rate) const
    {
        m = beta1 * m + (1.0f - beta1) * g;
        v = beta2 * v + (1.0f - beta2) * g * g;
        const double mHat = double(m) / corr1, vHat = double(v) / corr2;
        param -= float(double(rate) * mHat / (std::sqrt(vHat) + double(epsilon)));
    }
};

/// @brief Copy Gaussian i of a cloud into a packed row.
inline void packGaussian(const GaussianCloud& c, std::size_t i, float* p)
{
    for (int a = 0; a < 3; ++a) p[kParamMean + a] = c.means[3 * i + std::size_t(a)];
    for (int a = 0; a < 4; ++a) p[kParamRotation + a] = c.rotations[4 * i + std::size_t(a)];
    for (int a = 0; a < 3; ++a) p[kParamLogScale + a] = c.logScales[3 * i + std::size_t(a)];
    p[kParamLogit] = c.opacities[i];
    const float* h = c.shOf(i);
    for (int k = 0; k < c.shStride(); ++k) p[kParamSh + k] = h[k];
}

/// @brief Copy a packed row into Gaussian i of a cloud.
inline void unpackGaussian(const float* p, GaussianCloud& c, std::size_t i)
{
    for (int a = 0; a < 3; ++a) c.means[3 * i + std::size_t(a)] = p[kParamMean + a];
    for (int a = 0; a < 4; ++a) c.rotations[4 * i + std::size_t(a)] = p[kParamRotation + a];
    for (int a = 0; a < 3; ++a) c.logScales[3 * i + std::size_t(a)] = p[kParamLogScale + a];
    c.opacities[i] = p[kParamLogit];
    float* h = c.shOf(i);
    for (int k = 0; k < c.shStride(); ++k) h[k] = p[kParamSh + k];
}

} // namespace splatwarp
