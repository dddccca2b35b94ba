#pragma once
/// @file FeatureField.h
/// @brief CPU evaluation of the radial features of a Gaussian cloud at arbitrary points:
///        F(x) = sum_i alpha_i G_i(x) H_i (all SH coefficients [K,3]), O(x) = sum_i alpha_i G_i(x),
///        G_i(x) = exp(-1/2 (x-mu_i)^T Sigma'_i^-1 (x-mu_i)) without normalisation constant.
///        A pair counts only where alpha_i G_i >= cutoff. Coverage comes from binning the
///        Gaussians' exact extents (GaussianBins), not from testing all pairs.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/Device.h"
#include "core/GaussianCloud.h"
#include "field/GaussianBins.h"
#include "field/GaussianMath.h"
#include "field/PreparedGaussian.h"
#include "field/SampleSet.h"

namespace splatwarp {

/// @brief Options of a feature evaluation.
struct FeatureOptions {
    float cutoff = kDefaultCutoff; ///< a pair counts only where alpha*G >= cutoff
    /// Isotropic low-pass filter variance added to every covariance (world units^2); the rest
    /// filter is lambda_lpf * spacing^2. 0 = no filter.
    float filterVariance = 0.0f;
    bool threaded = true;          ///< oneTBB over points (results identical to serial)
    /// Memory the CPU block evaluation's (block, Gaussian) pair lists may take (0: no limit; the
    /// sample grid's rest targets: what --max-memory leaves beside the grid). Refused past it,
    /// before allocating them.
    std::size_t maxListBytes = 0;
    /// Where evaluateFeaturesOn() (field/FeatureDevice.h) runs; evaluateFeatures() is always the
    /// CPU. Library default Cpu; the CLI passes `--device`.
    ResolvedDevice device;
};

/// @brief Work counters of an evaluation.
struct FeatureStats {
    std::uint64_t pairsTested = 0;       ///< (point, Gaussian) candidates looked at
    std::uint64_t pairsContributing = 0; ///< pairs with alpha*G >= cutoff
    std::uint64_t binEntries = 0;        ///< (cell, Gaussian) entries in the bins
    float binCellSize = 0.0f;            ///< bin cell edge used
};

/// @throws InputError for a non-positive cutoff or a negative filter variance
void checkFeatureOptions(const FeatureOptions& options);

/// @brief Evaluate F and O at m points on the CPU.
/// @param points    [m,3]
/// @param features  [m,K,3] output (K = cloud.shCoeffs()); may be null
/// @param opacity   [m] output; may be null
/// @note Each point sums its Gaussians in ascending index order, so threaded and serial runs
///       agree bit for bit.
void evaluateFeatures(const GaussianCloud& cloud, const float* points, std::size_t m, const FeatureOptions& options,
                      float* features, float* opacity, FeatureStats* stats = nullptr);

/// @brief Rest targets of a sample set: targetF, targetO = the cloud's features at the rest
///        positions (resized here), with the options' (isotropic rest) filter.
void evaluateSampleTargets(const GaussianCloud& cloud, SampleSet& samples, const FeatureOptions& options);

/// @brief Prepare every Gaussian of a cloud with an isotropic filter (see prepareGaussian()).
std::vector<PreparedGaussian> prepareCloud(const GaussianCloud& cloud, double filterVariance, double cutoff,
                                           bool threaded = true);

/// @brief Bin prepared Gaussians by their AABB (Gaussians that never contribute are left out).
/// @param cellSize  bin cell edge; <= 0 picks GaussianBins::suggestCellSize()
void binPreparedGaussians(const std::vector<PreparedGaussian>& gaussians, float cellSize, bool threaded,
                          GaussianBins& bins);

/// @brief Lower level: features of already prepared and binned Gaussians (used by Stage II for
///        the fixed contribution of static Gaussians).
/// @param sh        [N,K,3] SH of the Gaussians (same indexing as gaussians), stride shStride floats
void evaluatePreparedFeatures(const std::vector<PreparedGaussian>& gaussians, const float* sh, int shStride,
                              const GaussianBins& bins, const float* points, std::size_t m, float cutoff,
                              bool threaded, float* features, float* opacity, FeatureStats* stats = nullptr);

} // namespace splatwarp
