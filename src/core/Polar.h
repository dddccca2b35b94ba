#pragma once
/// @file Polar.h
/// @brief Polar decomposition M = R S of a 3x3 matrix in double (Stage I per Gaussian, the target
///        SH rotation of warped samples, held-out evaluation).
#include "core/SmallMath.h"

namespace splatwarp {

/// @brief M = R S with R a proper rotation (det +1) and S symmetric, via SVD. When det(U V^T) < 0
///        (a reflection) the smallest singular direction is flipped, so S has one negative
///        eigenvalue then.
void polarDecomposition(const Mat3d& m, Mat3d& r, Mat3d& s);

/// @brief The rotation R of polarDecomposition().
Mat3d polarRotation(const Mat3d& m);

} // namespace splatwarp
