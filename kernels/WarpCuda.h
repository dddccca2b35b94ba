#pragma once
/// @file WarpCuda.h
/// @brief Point and sample warping on the GPU (double precision, like the CPU): skin weights by
///        brute force over the graph nodes (deform/SkinWeightMath.h, same formula as
///        DeformationGraph::skinWeights; exact distance ties may pick other nodes than nanoflann),
///        skinning, polar rotation, target SH rotation and F_k. No CUDA types here.
#include <cstddef>

#include "deform/WarpDevice.h"

namespace splatwarp::cuda {

/// @brief DeformationGraph::skinWeights() on the current CUDA device (graph k <= kMaxSkinK).
/// @throws InputError for an empty graph or k > kMaxSkinK; DeviceMemoryError when a buffer does not fit
SkinWeights skinWeightsCuda(const DeformationGraph& graph, const float* points, std::size_t count);

/// @brief warpPoints() on the current CUDA device; warped/rotations are written only on success.
/// @throws InputError as warpPoints(); DeviceMemoryError when a buffer does not fit
void warpPointsCuda(const DeformationGraph& graph, const NodeTransforms& transforms, const float* points,
                    std::size_t count, float* warped, float* rotations, bool threaded);

/// @brief warpSamples() on the current CUDA device; the samples are written only on success.
/// @throws InputError as warpSamples(); DeviceMemoryError when a buffer does not fit
void warpSamplesCuda(SampleSet& samples, const DeformationGraph& graph, const NodeTransforms& transforms,
                     bool threaded);

} // namespace splatwarp::cuda
