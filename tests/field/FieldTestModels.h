#pragma once
/// @file FieldTestModels.h
/// @brief Random Gaussian clouds and the naive double-precision all-pairs feature evaluator
///        that is the reference for the CPU feature code (field and stage2 tests).
#include <cmath>
#include <random>
#include <vector>

#include "core/GaussianCloud.h"
#include "core/SmallMath.h"
#include "field/GaussianMath.h"

namespace splatwarp::test {

/// @brief n Gaussians with random centres in [-extent, extent]^3, random rotations (raw,
///        unnormalised quaternions), anisotropic scales in [sMin, sMax], logits in [-2, 4].
inline GaussianCloud randomCloud(std::size_t n, int degree, std::uint32_t seed, float extent = 1.0f,
                                 float sMin = 0.03f, float sMax = 0.25f)
{
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> pos(-extent, extent), u(-1.0f, 1.0f), logit(-2.0f, 4.0f),
        ls(std::log(sMin), std::log(sMax)), qn(0.5f, 2.0f);
    std::normal_distribution<float> nq(0.0f, 1.0f);
    GaussianCloud g;
    g.resize(n, degree);
    for (std::size_t i = 0; i < n; ++i) {
        for (int k = 0; k < 3; ++k) {
            g.means[3 * i + k] = pos(rng);
            g.logScales[3 * i + k] = ls(rng);
        }
        const float norm = qn(rng);
        Quatf q{nq(rng), nq(rng), nq(rng), nq(rng)};
        const float len = std::sqrt(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z);
        g.setRotation(i, {q.w / len * norm, q.x / len * norm, q.y / len * norm, q.z / len * norm});
        g.opacities[i] = logit(rng);
        for (int s = 0; s < g.shStride(); ++s) g.shOf(i)[s] = u(rng);
    }
    return g;
}

/// @brief Reference alpha*G of Gaussian i at x in double, isotropic filter variance v.
inline double referenceWeight(const GaussianCloud& g, std::size_t i, const Vec3d& x, double v)
{
    const Quatd q{g.rotations[4 * i], g.rotations[4 * i + 1], g.rotations[4 * i + 2], g.rotations[4 * i + 3]};
    const Vec3d s(std::exp(double(g.logScales[3 * i])), std::exp(double(g.logScales[3 * i + 1])),
                  std::exp(double(g.logScales[3 * i + 2])));
    const Mat3d cov = gaussianCovariance(q, s) + Mat3d::identity() * v;
    const Vec3d d = x - Vec3d(g.mean(i));
    const double alpha = 1.0 / (1.0 + std::exp(-double(g.opacities[i])));
    return alpha * std::exp(-0.5 * dot(d, cov.inverse() * d));
}

/// @brief Naive all-pairs features in double. Also counts pairs with w >= cutoff*(1+band)
///        ("sure") and w >= cutoff*(1-band) ("possible"), and the summed |w H| of pairs in the
///        band (what float rounding at the cutoff may add or drop).
struct ReferenceFeatures {
    std::vector<double> f, o, fBand, oBand;
    std::size_t sure = 0, possible = 0;
};

inline ReferenceFeatures referenceFeatures(const GaussianCloud& g, const std::vector<float>& pts, double v,
                                           double cutoff, double band = 1e-4)
{
    const std::size_t m = pts.size() / 3;
    const int stride = g.shStride();
    ReferenceFeatures r;
    r.f.assign(m * std::size_t(stride), 0.0);
    r.fBand.assign(m * std::size_t(stride), 0.0);
    r.o.assign(m, 0.0);
    r.oBand.assign(m, 0.0);
    for (std::size_t p = 0; p < m; ++p) {
        const Vec3d x(pts[3 * p], pts[3 * p + 1], pts[3 * p + 2]);
        for (std::size_t i = 0; i < g.size(); ++i) {
            const double w = referenceWeight(g, i, x, v);
            if (w >= cutoff * (1 + band)) ++r.sure;
            if (w >= cutoff * (1 - band)) ++r.possible;
            const bool inBand = w >= cutoff * (1 - band) && w < cutoff * (1 + band);
            if (inBand) r.oBand[p] += w;
            for (int s = 0; s < stride; ++s)
                if (inBand) r.fBand[p * std::size_t(stride) + std::size_t(s)] += std::fabs(w * g.shOf(i)[s]);
            if (w < cutoff) continue;
            r.o[p] += w;
            for (int s = 0; s < stride; ++s) r.f[p * std::size_t(stride) + std::size_t(s)] += w * g.shOf(i)[s];
        }
    }
    return r;
}

/// @brief Random points in [-extent, extent]^3.
inline std::vector<float> randomPoints(std::size_t m, std::uint32_t seed, float extent)
{
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(-extent, extent);
    std::vector<float> p(3 * m);
    for (float& v : p) v = u(rng);
    return p;
}

} // namespace splatwarp::test
