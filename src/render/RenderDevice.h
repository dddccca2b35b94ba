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

/// @brief renderGaussians() on a device, with the same result up to float rounding (the CPU
///        rasteriser is the reference). Auto picks CUDA when available (resolveDevice()); when the
///        GPU runs out of memory under Auto the image is rendered on the CPU (with a progress
///        message), under Cuda the DeviceMemoryError propagates.
/// @param used  when not null, receives the device that rendered (Cpu or Cuda)
/// @throws InputError when Cuda is requested but unavailable (see resolveDevice()), and as
///         renderGaussians() for bad inputs
Image renderGaussians(Device device, const GaussianCloud& cloud, const Camera& camera,
                      const RenderOptions& options = {}, Device* used = nullptr);

} // namespace splatwarp
