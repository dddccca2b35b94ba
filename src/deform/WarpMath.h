#pragma once
/// @file WarpMath.h
/// @brief Per-element warping on raw arrays, host/device (one source of truth for the CPU
///        warpPoints()/warpSamples() and the CUDA warping kernels): one skinned point with the
///        polar rotation of its local gradient, the target SH rotation of one sample, and the
///        deformation gradient F_k of one cell.
#include <cstddef>
#include <cstdint>

#include "core/HostDevice.h"
#include "core/Polar.h"
#include "core/SmallMath.h"
#include "deform/SkinningMath.h"
#include "sh/ShRotationMath.h"

namespace splatwarp {

/// @brief Warp point p (row p of points [P,3], of nodes/weights [P,k]): warped [P,3] = skinned
///        position; rotations [P,9] (row-major, may be null) = polar rotation of sum_j w_j A_j.
SPLATWARP_HOST_DEVICE void warpPoint(const NodeAffine* affines, const std::int32_t* nodes, const float* weights,
                                     std::size_t k, const float* points, std::size_t p, float* warped,
                                     float* rotations)
{
    const float* x = points + 3 * p;
    const Vec3d y = skinAffinePoint(affines, nodes, weights, k, p, Vec3d(x[0], x[1], x[2]));
    for (int a = 0; a < 3; ++a) warped[3 * p + std::size_t(a)] = float(y[a]);
    if (!rotations) return;
    const Mat3d r = polarRotationFast(skinAffineGradient(affines, nodes, weights, k, p));
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) rotations[9 * p + std::size_t(3 * i + j)] = float(r.m[i][j]);
}

/// @brief Rotate one sample's target SH features [K,3] by a row-major float rotation [9] (as
///        warpPoint() stores it).
SPLATWARP_HOST_DEVICE void rotateSampleFeatures(const ShRotationTables& tables, const float* rotation, int shDegree,
                                                float* features)
{
    Mat3d rot;
    for (int i = 0; i < 9; ++i) rot.m[i / 3][i % 3] = rotation[i];
    rotateSh(tables, rot, shDegree, features);
}

/// @brief F_k of cell c: least-squares affine fit of the warped positions of the cell's 8 corner
///        samples against their rest offsets from the corners' centroid, F = (P Q^T)(Q Q^T)^-1.
///        Samples are [cells, n^3] in (a, b, c) row-major order; out: [9] row-major.
SPLATWARP_HOST_DEVICE void cellGradient(const float* restPositions, const float* warpedPositions, int n,
                                        std::size_t c, float* out)
{
    const std::size_t perCell = std::size_t(n) * std::size_t(n) * std::size_t(n);
    Vec3d rest[8], warped[8], restMean, warpedMean;
    int q = 0;
    for (int a = 0; a < n; a += n - 1)
        for (int bb = 0; bb < n; bb += n - 1)
            for (int cc = 0; cc < n; cc += n - 1, ++q) {
                const std::size_t s = c * perCell + std::size_t((a * n + bb) * n + cc);
                rest[q] = Vec3d(restPositions[3 * s], restPositions[3 * s + 1], restPositions[3 * s + 2]);
                warped[q] = Vec3d(warpedPositions[3 * s], warpedPositions[3 * s + 1], warpedPositions[3 * s + 2]);
                restMean += rest[q];
                warpedMean += warped[q];
            }
    restMean *= 1.0 / 8.0;
    warpedMean *= 1.0 / 8.0;
    Mat3d pq, qq;
    for (int k = 0; k < 8; ++k) {
        const Vec3d p = warped[k] - warpedMean, r = rest[k] - restMean;
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) {
                pq.m[i][j] += p[i] * r[j];
                qq.m[i][j] += r[i] * r[j];
            }
    }
    const Mat3d f = pq * qq.inverse();
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) out[3 * i + j] = float(f.m[i][j]);
}

} // namespace splatwarp
