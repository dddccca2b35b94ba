#pragma once
/// @file NodeTransforms.h
/// @brief Per-node affine transforms of the deformation graph and embedded-deformation skinning:
///        v' = sum_j w_j (A_j (v - g_j) + g_j + t_j).
#include <cstddef>
#include <vector>

#include "core/SmallMath.h"
#include "deform/DeformationGraph.h"
#include "deform/SkinningMath.h"

namespace splatwarp {

/// @brief Affine part A_j and translation t_j of every graph node, [J] each.
struct NodeTransforms {
    std::vector<Mat3d> A;
    std::vector<Vec3d> t;
    /// @brief n identity transforms (A = I, t = 0).
    static NodeTransforms identity(std::size_t n);
    std::size_t size() const { return t.size(); }
};

/// @brief Deformed position of point i of the weights, at rest position v:
///        v' = sum_j w_j (A_j (v - g_j) + g_j + t_j).
Vec3d skinPoint(const DeformationGraph& graph, const NodeTransforms& transforms, const SkinWeights& weights,
                std::size_t i, const Vec3d& v);

/// @brief Local deformation gradient of point i: sum_j w_j A_j.
Mat3d skinGradient(const DeformationGraph& graph, const NodeTransforms& transforms, const SkinWeights& weights,
                   std::size_t i);

/// @brief The node transforms as affine maps A_j v + b_j, [J] (the layout of the CUDA skinning kernels).
std::vector<NodeAffine> nodeAffines(const DeformationGraph& graph, const NodeTransforms& transforms);

/// @brief The node transforms as affine maps A_j v + b_j (b_j = g_j + t_j - A_j g_j), precomputed
///        once, so each skinned point costs one 3x4 product per node. Same values as skinPoint()
///        and skinGradient() up to rounding; those stay as the plain reference.
class AffineSkinning {
public:
    AffineSkinning(const DeformationGraph& graph, const NodeTransforms& transforms);
    /// @brief Deformed position of point i of the weights, at rest position v.
    Vec3d point(const SkinWeights& weights, std::size_t i, const Vec3d& v) const;
    /// @brief Local deformation gradient of point i: sum_j w_j A_j.
    Mat3d gradient(const SkinWeights& weights, std::size_t i) const;
    /// @brief The affine maps, [J].
    const std::vector<NodeAffine>& affines() const { return mNodes; }

private:
    std::vector<NodeAffine> mNodes;
};

} // namespace splatwarp
