#pragma once
/// @file StretchedView.h
/// @brief The most stretched region of a deformation and a close-up picture of it: where Stage I
///        (rotations only, at the Gaussians' scale) and Stage II (fitted to the stretched field)
///        differ most (`deform --render` writes it as stretched.png).
#include <optional>

#include "core/GaussianCloud.h"
#include "core/SmallMath.h"
#include "field/SampleSet.h"
#include "image/Image.h"
#include "render/Rasterizer.h"

namespace splatwarp {

/// @brief The cell whose deformation gradient stretches most.
struct StretchedRegion {
    std::size_t cell = 0;
    double stretch = 1;      ///< largest singular value of the cell's F
    Vec3d stretchAxis;       ///< the warped direction of that stretch (unit)
    Vec3d restCentre;        ///< centre of the cell's samples at rest
    Vec3d warpedCentre;      ///< ... and after the deformation
    Mat3d rotation;          ///< polar rotation of F (the cell's rigid part)
    double radius = 0;       ///< half-width of the close-up: the stretched cell and about one cell around
};

/// @brief Among the cells not skipped whose largest target opacity is at least minTarget (so
///        the region holds matter, not just a stretched void), the one with the largest
///        singular value of F; none when no cell qualifies.
/// @param warped  samples after warpSamples() (cellGradient set)
std::optional<StretchedRegion> mostStretchedRegion(const SampleSet& warped, float minTarget = 0.1f);

/// @brief Rest (moved rigidly by the region's rotation, so it lands where the region went: what
///        an undeformed copy would look like there) | Stage I | Stage II, each cropped to the
///        Gaussians whose centres lie within the region's radius (no occluders), seen from two
///        views across the stretch axis, size x size pixels each.
Image renderStretchedCloseUp(const GaussianCloud& rest, const GaussianCloud& stage1, const GaussianCloud& stage2,
                             const StretchedRegion& region, int size, const RenderOptions& render);

} // namespace splatwarp
