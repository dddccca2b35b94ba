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

/// @brief Sample index of corner q (bits x, y, z) of a cell of `axis` samples per axis whose
///        samples start at `first`: (a, b, c) row-major; a fine cell (axis != base n) holds its
///        samples octant by octant, n^3 each (SampleSet::cellAxis).
SPLATWARP_HOST_DEVICE std::size_t cellCornerSample(std::size_t first, int axis, int base, int q)
{
    const int qx = q >> 2, qy = (q >> 1) & 1, qz = q & 1;
    const int n = axis == base ? axis : axis / 2; // samples per axis of one run
    const std::size_t run = axis == base ? 0 : std::size_t(q) * std::size_t(n) * std::size_t(n) * std::size_t(n);
    return first + run + std::size_t((qx * (n - 1) * n + qy * (n - 1)) * n + qz * (n - 1));
}

/// @brief F_k of the cell whose samples start at `first` (axis samples per axis, base n: see
///        cellCornerSample()): least-squares affine fit of the warped positions of its 8 corner
///        samples against their rest offsets from the corners' centroid, F = (P Q^T)(Q Q^T)^-1;
///        out: [9] row-major.
SPLATWARP_HOST_DEVICE void cellGradientAt(const float* restPositions, const float* warpedPositions, std::size_t first,
                                          int axis, int base, float* out)
{
    Vec3d rest[8], warped[8], restMean, warpedMean;
    for (int q = 0; q < 8; ++q) {
        const std::size_t s = cellCornerSample(first, axis, base, q);
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

/// @brief F_k of cell c of a uniform lattice: samples [cells, n^3] in (a, b, c) row-major order.
SPLATWARP_HOST_DEVICE void cellGradient(const float* restPositions, const float* warpedPositions, int n,
                                        std::size_t c, float* out)
{
    cellGradientAt(restPositions, warpedPositions, c * std::size_t(n) * std::size_t(n) * std::size_t(n), n, n, out);
}

} // namespace splatwarp
