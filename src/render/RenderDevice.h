#pragma once
/// @file RenderDevice.h
/// @brief The splat rasteriser on the chosen device: the CPU one (Rasterizer.h) or the CUDA one
///        the kernels register at start-up (the core library cannot link them; see
///        stage2/StageTwoDevice.h for the same pattern).
#include "core/Device.h"
#include "render/Rasterizer.h"

namespace splatwarp {

/// @brief Signature of a rasteriser implementation (that of renderGaussians()).
using RenderFunction = Image (*)(const GaussianCloud&, const Camera&, const RenderOptions&);

/// @brief Register the CUDA rasteriser (nullptr unregisters). Called by cuda::registerBackends().
void registerRenderCuda(RenderFunction cuda);

/// @brief renderGaussians() on options.device, with the same result up to float rounding (the
///        CPU rasteriser is the reference). When the GPU cannot take it (DeviceLimitError: out of
///        memory, a count past its indices) under Auto the image is rendered on the CPU (with a
///        progress message), under Cuda the DeviceLimitError propagates.
/// @param used  when not null, receives the device that rendered (Cpu or Cuda)
/// @throws InputError when Cuda was asked and no CUDA rasteriser is registered, and as
///         renderGaussians() for bad inputs
Image renderGaussiansOn(const GaussianCloud& cloud, const Camera& camera, const RenderOptions& options = {},
                        Device* used = nullptr);

} // namespace splatwarp
