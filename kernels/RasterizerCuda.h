#pragma once
/// @file RasterizerCuda.h
/// @brief The 3DGS splat rasteriser on the GPU: same inputs, outputs and semantics as
///        renderGaussians() (render/Rasterizer.h, the reference). No CUDA types here.
#include "render/Rasterizer.h"

namespace splatwarp::cuda {

/// @brief renderGaussians() on the current CUDA device: per-Gaussian projection, (tile, depth)
///        keys sorted by a stable radix sort (ties in depth keep the Gaussian index order, as on
///        the CPU), then one thread per pixel composites its tile's splats front to back.
///        Deterministic; equal to the CPU image up to the rounding of expf (see the .cu).
/// @return RGBA linear float image of the camera's size (as renderGaussians()).
/// @throws InputError as renderGaussians(); DeviceMemoryError when a buffer does not fit (the
///         message names it); Error for any other CUDA failure. options.threaded is ignored.
Image renderGaussiansCuda(const GaussianCloud& cloud, const Camera& camera, const RenderOptions& options = {});

} // namespace splatwarp::cuda
