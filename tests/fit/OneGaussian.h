#pragma once
/// @file OneGaussian.h
/// @brief One known Gaussian sampled at voxel centres (moment and volume-fit tests).
#include <cmath>

#include "core/SmallMath.h"
#include "fit/MomentInit.h"

namespace splatwarp::test {

/// @brief One Gaussian (alpha, mean, R, scales); voxel (i,j,k) is centred at s*(i,j,k).
struct OneGaussian {
    double alpha = 0.6, s = 0.1;
    Vec3d mean{0.31, -0.17, 0.08};
    Vec3d scales{0.45, 0.3, 0.2};
    Quatd q{0.9, 0.3, -0.2, 0.25};
    Mat3d cov() const
    {
        const Mat3d r = quatToMatrix(q);
        Mat3d c;
        for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b) {
                double v = 0;
                for (int k = 0; k < 3; ++k) v += r.m[a][k] * scales[k] * scales[k] * r.m[b][k];
                c.m[a][b] = v;
            }
        return c;
    }
    double value(const Vec3d& x) const
    {
        const Mat3d r = quatToMatrix(q);
        const Vec3d d = x - mean;
        double e = 0;
        for (int k = 0; k < 3; ++k) {
            const double t = r.m[0][k] * d.x + r.m[1][k] * d.y + r.m[2][k] * d.z;
            e += t * t / (scales[k] * scales[k]);
        }
        return alpha * std::exp(-0.5 * e);
    }
    /// @brief Voxels (i,j,k) in [-half, half]^3 at s*(i,j,k) with features value * (0.7, -0.2, 0.1).
    VoxelSamples voxels(int half) const
    {
        VoxelSamples v;
        v.voxelSize = s;
        for (int i = -half; i <= half; ++i)
            for (int j = -half; j <= half; ++j)
                for (int k = -half; k <= half; ++k) {
                    const Vec3d x(i * s, j * s, k * s);
                    const float o = float(value(x));
                    if (o <= 0) continue;
                    for (double c : {x.x, x.y, x.z}) v.positions.push_back(float(c));
                    v.values.push_back(o);
                    for (float f : {0.7f, -0.2f, 0.1f}) v.features.push_back(o * f);
                }
        return v;
    }
};

} // namespace splatwarp::test
