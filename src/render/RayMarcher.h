#pragma once
/// @file RayMarcher.h
/// @brief A small emission-absorption ray marcher for volumes (`from-vdb --render` shows it beside
///        the splats, same camera): midpoint steps through the volume's box, per step
///        T *= exp(-sigma dt), colour += T (1 - exp(-sigma dt)) c.
#include <cstddef>
#include <functional>

#include "core/SmallMath.h"
#include "image/Image.h"
#include "render/Camera.h"

namespace splatwarp {

/// @brief Extinction (per world unit) and RGB (display values, as the colour grid) at m world points [m,3] -> sigma [m], rgb [m,3].
using VolumeLookup = std::function<void(const float* points, std::size_t m, float* sigma, float* rgb)>;

/// @brief Options of rayMarch().
struct RayMarchOptions {
    double step = 0.0;                  ///< world units between samples (> 0)
    Vec3f background{0.0f, 0.0f, 0.0f}; ///< RGB behind the volume (display values, as the splat colours)
    bool threaded = true;               ///< oneTBB over image rows
};

/// @brief Render the volume inside the box [lo, hi] from a camera.
/// @return RGBA image of display values: RGB = colour + T * background, A = 1 - T (as renderGaussians()).
/// @throws InputError for a non-positive step or a camera without a positive size
Image rayMarch(const VolumeLookup& lookup, const Vec3d& lo, const Vec3d& hi, const Camera& camera,
               const RayMarchOptions& options);

} // namespace splatwarp
