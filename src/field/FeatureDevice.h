#pragma once
/// @file FeatureDevice.h
/// @brief Rest sample targets on the chosen device: the CPU path (FeatureField.h) or the CUDA one
///        the kernels register at start-up (the core library cannot link them), which looks the
///        Gaussians' cells up in the NanoVDB cell index grid (field/CellTargetMath.h).
#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/Device.h"
#include "field/CellIndexGrid.h"
#include "field/FeatureField.h"
#include "field/PreparedGaussian.h"

namespace splatwarp {

/// @brief Prepared Gaussians and their SH as plain host arrays.
struct PreparedCloudView {
    const PreparedGaussian* gaussians = nullptr; ///< [N] prepared with the evaluation's filter and cutoff
    std::size_t count = 0;                       ///< N
    const float* sh = nullptr;                   ///< [N, shStride]
    int shStride = 0;
    float cutoff = kDefaultCutoff;
};

/// @brief The view of `prepared` (from prepareCloud(cloud, ...)) with the cloud's SH.
inline PreparedCloudView preparedView(const std::vector<PreparedGaussian>& prepared, const GaussianCloud& cloud,
                                      float cutoff)
{
    return {prepared.data(), prepared.size(), cloud.sh.data(), cloud.shStride(), cutoff};
}

/// @brief The inputs of a cell-list target evaluation, as plain host arrays.
struct SampleTargetsProblem {
    PreparedCloudView cloud;                     ///< prepared with the rest filter and cutoff
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
///        bin candidates. Must throw DeviceMemoryError when the GPU runs out of memory and
///        DeviceLimitError for counts past its indices (never InputError: the CPU can take those).
using SampleTargetsFunction = void (*)(const SampleTargetsProblem&, float* features, float* opacity,
                                       FeatureStats* stats);

/// @brief The inputs of a feature evaluation at arbitrary points, as plain host arrays.
struct FeaturePointsProblem {
    PreparedCloudView cloud;                     ///< prepared with the options' filter and cutoff
    const float* points = nullptr;               ///< [M,3]
    std::size_t count = 0;                       ///< M
};

/// @brief A feature evaluation at points (features [M, shStride], opacity [M], either may be
///        null): the semantics of evaluateFeatures(); stats as there (the bins differ, so
///        pairsTested and binEntries do, pairsContributing does not). DeviceMemoryError when
///        the GPU runs out of memory.
using FeaturesFunction = void (*)(const FeaturePointsProblem&, float* features, float* opacity, FeatureStats* stats);

/// @brief Register the CUDA feature evaluation (nullptr unregisters).
void registerFeaturesCuda(FeaturesFunction cuda);

/// @brief evaluateFeatures() on options.device: CUDA when registered and resolved (Auto falls
///        back to the CPU on out-of-GPU-memory with a progress line), else the CPU.
/// @return the device that ran
/// @throws InputError as evaluateFeatures(), or when Cuda was asked and no CUDA version is registered
Device evaluateFeaturesOn(const GaussianCloud& cloud, const float* points, std::size_t m, const FeatureOptions& options,
                          float* features, float* opacity, FeatureStats* stats = nullptr);

/// @brief Register the CUDA sample-target evaluation (nullptr unregisters). Called by
///        cuda::registerBackends().
void registerSampleTargetsCuda(SampleTargetsFunction cuda);

/// @brief The registered CUDA sample-target evaluation, or null.
SampleTargetsFunction sampleTargetsCuda();

} // namespace splatwarp
