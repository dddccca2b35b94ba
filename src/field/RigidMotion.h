#pragma once
/// @file RigidMotion.h
/// @brief Apply a rigid motion to a Gaussian cloud (means, rotations and SH turned together):
///        the reference deformation for rigid checks of the field error and Stage II.
#include "core/GaussianCloud.h"
#include "core/SmallMath.h"

namespace splatwarp {

/// @brief The cloud moved by x -> r x + t: means, rotations (r R_i, stored unit w >= 0) and SH
///        rotated by r; scales, opacities unchanged.
/// @param r  a proper rotation matrix
GaussianCloud rigidlyMoved(const GaussianCloud& cloud, const Mat3d& r, const Vec3d& t);

} // namespace splatwarp
