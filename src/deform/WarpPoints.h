#pragma once
/// @file WarpPoints.h
/// @brief Push any point set through a solved deformation: skinned positions and the rotation of
///        the local deformation gradient (for rotating SH features). Used for field samples and
///        held-out evaluation points.
#include <cstddef>

#include "deform/DeformationGraph.h"
#include "deform/NodeTransforms.h"

namespace splatwarp {

/// @brief warped[p] = sum_j w_j (A_j (X_p - g_j) + g_j + t_j); rotations[p] = polar rotation of
///        sum_j w_j A_j (row-major 3x3). Skin weights are computed in bounded batches.
/// @param points    [P,3] rest positions X
/// @param warped    [P,3] out
/// @param rotations [P,9] out, or null when not needed
void warpPoints(const DeformationGraph& graph, const NodeTransforms& transforms, const float* points,
                std::size_t count, float* warped, float* rotations, bool threaded = true);

} // namespace splatwarp
