#pragma once
/// @file TestGaussians.h
/// @brief Small hand-made clouds and lattices shared by the split tests (stage2/Densify, deform/CurveSplit).
#include <cmath>
#include <cstddef>
#include <vector>

#include "core/GaussianCloud.h"

namespace splatwarp::test {

/// @brief Three overlapping Gaussians of SH degree 1: rotated, anisotropic, opacities near 1, mid
///        and low; every sigma >= 0.08, all within [-1.2, 1.2]^3 to 4 sigma.
inline GaussianCloud threeGaussians()
{
    GaussianCloud g;
    g.resize(3, 1);
    const float means[3][3] = {{0.0f, 0.0f, 0.0f}, {0.25f, -0.1f, 0.05f}, {-0.2f, 0.15f, -0.1f}};
    const float scales[3][3] = {{0.30f, 0.12f, 0.08f}, {0.10f, 0.22f, 0.09f}, {0.09f, 0.10f, 0.18f}};
    const float quats[3][4] = {{0.9f, 0.2f, -0.3f, 0.1f}, {0.7f, -0.1f, 0.5f, 0.4f}, {1.0f, 0.0f, 0.0f, 0.0f}};
    const float alphas[3] = {0.97f, 0.5f, 0.06f};
    for (std::size_t i = 0; i < 3; ++i) {
        g.setMean(i, Vec3f{means[i][0], means[i][1], means[i][2]});
        g.setRotation(i, Quatf{quats[i][0], quats[i][1], quats[i][2], quats[i][3]});
        for (int a = 0; a < 3; ++a) g.logScales[3 * i + std::size_t(a)] = std::log(scales[i][a]);
        g.opacities[i] = std::log(alphas[i] / (1.0f - alphas[i]));
        for (int c = 0; c < g.shStride(); ++c) g.shOf(i)[c] = 0.3f * float(i + 1) - 0.07f * float(c);
    }
    return g;
}

/// @brief The n^3 points lo + h (x, y, z), x fastest, as [n^3, 3] floats (midpoint-rule lattices).
inline std::vector<float> latticePoints(double h, double lo, int n)
{
    std::vector<float> points;
    points.reserve(std::size_t(3) * std::size_t(n) * std::size_t(n) * std::size_t(n));
    for (int z = 0; z < n; ++z)
        for (int y = 0; y < n; ++y)
            for (int x = 0; x < n; ++x)
                for (double v : {lo + h * x, lo + h * y, lo + h * z}) points.push_back(float(v));
    return points;
}

} // namespace splatwarp::test
