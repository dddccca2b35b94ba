#pragma once
/// @file SkinningMath.h
/// @brief Embedded-deformation skinning of one point on raw arrays, host/device: the one
///        implementation behind AffineSkinning (CPU) and the CUDA skinning kernels.
#include <cstddef>
#include <cstdint>

#include "core/HostDevice.h"
#include "core/SmallMath.h"

namespace splatwarp {

/// @brief Node transform j as the affine map A_j v + b_j, b_j = g_j + t_j - A_j g_j (plain data,
///        copied to the GPU as is).
struct NodeAffine {
    double a[3][3];
    double b[3];
};

/// @brief Deformed position of point q at rest position v: sum_e w_e (A_n v + b_n) / sum_e w_e
///        over the k entries of q in nodes/weights ([P,k] each, row-major).
SPLATWARP_HOST_DEVICE Vec3d skinAffinePoint(const NodeAffine* affines, const std::int32_t* nodes, const float* weights,
                                            std::size_t k, std::size_t q, const Vec3d& v)
{
    double o0 = 0.0, o1 = 0.0, o2 = 0.0, sum = 0.0;
    for (std::size_t e = q * k; e < (q + 1) * k; ++e) {
        const double wt = double(weights[e]);
        const NodeAffine& n = affines[std::size_t(nodes[e])];
        o0 += wt * (n.a[0][0] * v.x + n.a[0][1] * v.y + n.a[0][2] * v.z + n.b[0]);
        o1 += wt * (n.a[1][0] * v.x + n.a[1][1] * v.y + n.a[1][2] * v.z + n.b[1]);
        o2 += wt * (n.a[2][0] * v.x + n.a[2][1] * v.y + n.a[2][2] * v.z + n.b[2]);
        sum += wt;
    }
    // Divide by the sum of the float weights (1 up to rounding) so rigid motions stay exact in double.
    const double inv = 1.0 / sum;
    return Vec3d(o0 * inv, o1 * inv, o2 * inv);
}

/// @brief Local deformation gradient of point q: sum_e w_e A_n / sum_e w_e.
SPLATWARP_HOST_DEVICE Mat3d skinAffineGradient(const NodeAffine* affines, const std::int32_t* nodes,
                                               const float* weights, std::size_t k, std::size_t q)
{
    Mat3d out;
    double sum = 0.0;
    for (std::size_t e = q * k; e < (q + 1) * k; ++e) {
        const double wt = double(weights[e]);
        const NodeAffine& n = affines[std::size_t(nodes[e])];
        for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 3; ++c) out.m[r][c] += wt * n.a[r][c];
        sum += wt;
    }
    return out * (1.0 / sum);
}

} // namespace splatwarp
