#pragma once
/// @file WarpDevice.h
/// @brief Point and sample warping on the chosen device: the CPU warpPoints()/warpSamples() or
///        the CUDA versions the kernels register at start-up (the core library cannot link them).
///        The GPU also computes the skin weights (brute force, same formula; exact distance ties
///        may pick other nodes than the CPU's nanoflann).
#include <cstddef>

#include "core/Device.h"
#include "deform/Deformation.h"
#include "deform/SampleWarp.h"
#include "deform/WarpPoints.h"

namespace splatwarp {

/// @brief Signature of warpPoints(). A GPU version writes warped/rotations only on success.
using WarpPointsFunction = void (*)(const DeformationGraph&, const NodeTransforms&, const float*, std::size_t, float*,
                                    float*, bool);
/// @brief Signature of warpSamples(). A GPU version leaves the samples untouched when it throws.
using WarpSamplesFunction = void (*)(SampleSet&, const DeformationGraph&, const NodeTransforms&, bool);

/// @brief Register the CUDA warping (nullptr unregisters). Called by cuda::registerBackends().
void registerWarpCuda(WarpPointsFunction points, WarpSamplesFunction samples);

/// @brief Options of a warp on a device.
struct WarpOptions {
    ResolvedDevice device; ///< where it runs (see runOnDevice())
    bool threaded = true;  ///< oneTBB on the CPU
};

/// @brief warpPoints() on options.device (Auto: CPU on out-of-GPU-memory with a progress line;
///        Cuda: errors propagate).
/// @return the device that ran
/// @throws InputError when Cuda was asked and no CUDA warping is registered
Device warpPointsOn(const DeformationGraph& graph, const NodeTransforms& transforms, const float* points,
                    std::size_t count, float* warped, float* rotations, const WarpOptions& options = {});

/// @brief warpSamples() on options.device, as warpPointsOn(). Returns the device that ran.
Device warpSamplesOn(SampleSet& samples, const Deformation& deformation, const WarpOptions& options = {});

} // namespace splatwarp
