#pragma once
/// @file StageTwoParams.h
/// @brief The one packed parameter layout of Stage II (CPU and CUDA solvers): per moving
///        Gaussian mean 3, raw rotation quaternion 4, log-scale 3, logit opacity 1, then the SH
///        coefficients (stride floats), and the Adam update on it. Host/device.
#include <algorithm>
#include <cmath>
#include <cstddef>

#include "core/GaussianCloud.h"
#include "core/HostDevice.h"
#include "stage2/PairGradients.h"
#include "stage2/StageTwoOptions.h"

namespace splatwarp {

/// @brief Position learning rate at an iteration: exponential from lrPositionStart to
///        lrPositionEnd over the schedule (StageTwoOptions::scheduleLength()), then flat, times
///        the scene extent.
inline float stageTwoPositionRate(const StageTwoOptions& o, int iteration, float sceneExtent)
{
    const int n = o.scheduleLength();
    const double tFrac = n > 1 ? double(iteration) / double(n - 1) : 0.0;
    return float(double(o.lrPositionStart) *
                 std::pow(double(o.lrPositionEnd) / double(o.lrPositionStart), std::min(tFrac, 1.0)) *
                 double(sceneExtent));
}

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

/// @brief One step of the loop: the schedule's iteration (0-based; sets the position rate),
///        Adam's step count t (1-based: accepted steps so far plus one) and a factor on every
///        learning rate (step rejection shortens it, StageTwoOptions::rejectSteps).
struct StageTwoStep {
    int iteration = 0;
    int adamStep = 1;
    float rateScale = 1.0f;
};

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
    /// @brief The rates of a step: the options' (position rate from its schedule, scaled by the
    ///        scene extent), times the step's rate factor.
    static StepRates forStep(const StageTwoOptions& o, const StageTwoStep& s, float sceneExtent)
    {
        const float f = s.rateScale;
        return {f * stageTwoPositionRate(o, s.iteration, sceneExtent), f * o.lrRotation, f * o.lrLogScale,
                f * o.lrOpacity, f * o.lrSh};
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
    /// @brief Update the moments of a parameter with gradient g and return its step (float
    ///        moments, double step; the parameter moves by minus the step).
    SPLATWARP_HOST_DEVICE double delta(float& m, float& v, float g, float rate) const
    {
        m = beta1 * m + (1.0f - beta1) * g;
        v = beta2 * v + (1.0f - beta2) * g * g;
        const double mHat = double(m) / corr1, vHat = double(v) / corr2;
        return double(rate) * mHat / (std::sqrt(vHat) + double(epsilon));
    }
};

/// @brief One Adam step of a packed row. The mean's step is shortened to a Mahalanobis length of
///        at most maxMeanStep in the Gaussian's filtered covariance (0: no bound): Adam moves every
///        coordinate by about its rate whatever the gradient's size, and one scene-wide position
///        rate is several times the thickness of a flat Gaussian (StageTwoOptions::maxMeanStep).
///        Returns the step's first-order energy decrease on the row, the sum of gradient times
///        step (the step rule compares the energy's actual decrease with it).
SPLATWARP_HOST_DEVICE double adamStepRow(const AdamStep& adam, const StepRates& rates, const Mat3d& filter,
                                         float maxMeanStep, int perG, float* p, float* m, float* v, const float* g)
{
    Vec3d d;
    for (int a = 0; a < 3; ++a) d[a] = adam.delta(m[a], v[a], g[a], rates.position);
    if (maxMeanStep > 0) {
        const GaussianParams<double> q = unpackParams(p);
        const Vec3d sc(std::exp(q.logScale.x), std::exp(q.logScale.y), std::exp(q.logScale.z));
        const double len2 = dot(d, filteredCovariance(q.rotation, sc, filter).inverse() * d);
        const double cap = double(maxMeanStep);
        if (len2 > cap * cap) d *= cap / std::sqrt(len2);
    }
    double decrease = 0;
    for (int a = 0; a < 3; ++a) {
        p[kParamMean + a] -= float(d[a]);
        decrease += double(g[a]) * d[a];
    }
    for (int c = kParamRotation; c < perG; ++c) {
        const double step = adam.delta(m[c], v[c], g[c], rates.of(c));
        p[c] -= float(step);
        decrease += double(g[c]) * step;
    }
    return decrease;
}

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
