#pragma once
/// @file FeaturesCuda.h
/// @brief Rest sample targets on the GPU through the NanoVDB cell index grid (see
///        field/FeatureDevice.h for the contract, field/CellTargetMath.h for the per-element
///        functions the kernels wrap). No CUDA types here.
#include "field/FeatureDevice.h"

namespace splatwarp::cuda {

/// @brief The host-side validation evaluateSampleTargetsCuda() runs before any CUDA call.
/// @throws InputError for a bad index grid, SH stride or cell size, missing arrays, or a
///         sample whose cell is not one of the problem's cells
void checkSampleTargets(const SampleTargetsProblem& problem);

/// @brief Evaluate targetF [M, shStride] and targetO [M] of every sample on the current CUDA
///        device; the outputs are written only at the end. stats: pairsContributing (as the CPU
///        path) and pairsTested (the sum over samples of their cell's list length; cells may
///        hold different sample counts, e.g. fine cells).
/// @throws InputError as checkSampleTargets(); DeviceMemoryError when a buffer does not fit (the
///         message names it); DeviceLimitError when the pairs exceed one 32-bit sort; Error for
///         other CUDA failures
void evaluateSampleTargetsCuda(const SampleTargetsProblem& problem, float* features, float* opacity,
                               FeatureStats* stats);

/// @brief evaluateFeatures() at arbitrary points on the current CUDA device (see
///        FeaturesFunction in field/FeatureDevice.h): the Gaussians' pruning boxes binned on the
///        GPU (BoxBins), each point sums its bin's Gaussians in ascending index order.
/// @throws InputError for bad inputs; DeviceMemoryError when a buffer does not fit;
///         DeviceLimitError for counts past its 32-bit indices; Error else
void evaluateFeaturesCuda(const FeaturePointsProblem& problem, float* features, float* opacity, FeatureStats* stats);

} // namespace splatwarp::cuda
