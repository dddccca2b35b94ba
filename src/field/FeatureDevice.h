#pragma once
/// @file FeatureDevice.h
/// @brief Rest sample targets on the chosen device: the CPU path (FeatureField.h) or the CUDA one
///        the kernels register at start-up (the core library cannot link them), which looks the
///        Gaussians' cells up in the NanoVDB cell index grid (field/CellTargetKernels.h).
#include <cstddef>
#include <cstdint>

#include "core/Device.h"
#include "field/CellIndexGrid.h"
#include "field/FeatureField.h"
#include "field/PreparedGaussian.h"

namespace splatwarp {

/// @brief The inputs of a cell-list target evaluation, as plain host arrays.
struct SampleTargetsProblem {
    const PreparedGaussian* gaussians = nullptr; ///< [N] prepared with the rest filter and cutoff
    std::size_t gaussianCount = 0;
    const float* sh = nullptr;                   ///< [N, shStride]
    int shStride = 0;
    float cutoff = kDefaultCutoff;
    const CellIndexGrid* index = nullptr;        ///< the sample grid's cells (NanoVDB Int32)
    double cellSize = 0.0;                       ///< h: cell (i,j,k) spans [i h, (i+1) h)
    const float* positions = nullptr;            ///< [M,3] rest sample positions
    const std::int32_t* sampleCell = nullptr;    ///< [M] active cell of each sample
    std::size_t samples = 0;                     ///< M
    std::size_t cells = 0;                       ///< C
};

/// @brief A target evaluation: features [M, shStride] and opacity [M] for every sample; stats
///        gets pairsContributing (as the CPU path) and pairsTested = sum over cells of
///        (Gaussians in the cell's list) x (samples of the cell), which differs from the CPU's
///        bin candidates. Must throw DeviceMemoryError when the GPU runs out of memory.
using SampleTargetsFunction = void (*)(const SampleTargetsProblem&, float* features, float* opacity,
                                       FeatureStats* stats);

/// @brief Register the CUDA sample-target evaluation (nullptr unregisters). Called by
///        cuda::registerBackends().
void registerSampleTargetsCuda(SampleTargetsFunction cuda);

/// @brief The registered CUDA sample-target evaluation, or null.
SampleTargetsFunction sampleTargetsCuda();

} // namespace splatwarp
