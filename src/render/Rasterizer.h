#pragma once
/// @file Rasterizer.h
/// @brief CPU 3DGS splat rasteriser: EWA projection, 16x16 screen tiles, depth-sorted
///        front-to-back alpha compositing (oneTBB over tiles). Deterministic: every pixel composites
///        the same splats in the same (depth, index) order whatever the thread count.
#include "core/Device.h"
#include "core/GaussianCloud.h"
#include "core/SmallMath.h"
#include "image/Image.h"
#include "render/Camera.h"

namespace splatwarp {

/// @brief Options for renderGaussians(). The rasteriser constants (near plane, dilation, alpha
///        limits) are fixed 3DGS values, see render/SplatProjection.h.
struct RenderOptions {
    Vec3f background{0.0f, 0.0f, 0.0f}; ///< RGB behind the splats (display values, as the splat colours)
    bool threaded = true;               ///< oneTBB over Gaussians and tiles
    ResolvedDevice device;              ///< where renderGaussiansOn() (render/RenderDevice.h) renders
};

/// @brief Render a model from a camera.
/// @return RGBA float image of display values (image/Image.h) of the camera's size: RGB = composited colour + T * background,
///         A = 1 - T (T = final transmittance).
/// @throws InputError for an inconsistent model or a camera without a positive size/focal length.
Image renderGaussians(const GaussianCloud& cloud, const Camera& camera, const RenderOptions& options = {});

/// @brief The input checks of renderGaussians(), for other rasterisers with its contract.
/// @throws InputError for an inconsistent model or a camera without a positive size/focal length.
void checkRenderInputs(const GaussianCloud& cloud, const Camera& camera);

} // namespace splatwarp
