#pragma once
/// @file WarpCuda.h
/// @brief Point and sample warping on the GPU (double precision skinning, like the CPU): skin
///        weights come from the CPU (DeformationGraph::skinWeights, in batches) and are uploaded;
///        the GPU skins, takes the polar rotation, rotates the target SH and computes F_k. No CUDA
///        types here.
#include <cstddef>

#include "deform/WarpDevice.h"

namespace splatwarp::cuda {

/// @brief warpPoints() on the current CUDA device; warped/rotations are written only on success.
/// @throws InputError as warpPoints(); DeviceMemoryError when a buffer does not fit
void warpPointsCuda(const DeformationGraph& graph, const NodeTransforms& transforms, const float* points,
                    std::size_t count, float* warped, float* rotations, bool threaded);

/// @brief warpSamples() on the current CUDA device; the samples are written only on success.
/// @throws InputError as warpSamples(); DeviceMemoryError when a buffer does not fit
void warpSamplesCuda(SampleSet& samples, const DeformationGraph& graph, const NodeTransforms& transforms,
                     bool threaded);

} // namespace splatwarp::cuda
