#pragma once
/// @file VolumeFit.h
/// @brief Fit Gaussians to a sampled field with no deformation (`from-vdb`): the Stage II
///        engine (every Gaussian moving, samples = voxels) in rounds, with pruning of
///        transparent Gaussians and splitting where the residual stays high between rounds.
#include <cstddef>
#include <vector>

#include "core/GaussianCloud.h"
#include "field/SampleSet.h"
#include "stage2/StageTwo.h"

namespace splatwarp {

/// @brief Options of fitToSamples().
struct VolumeFitOptions {
    int iterations = 100;     ///< Stage II iterations over all rounds together
    int rounds = 1;           ///< rounds of fitting; prune and split between rounds
    float pruneAlpha = 1.0f / 255.0f; ///< Gaussians below this opacity are removed between rounds
    /// Share of the budget held back at the start and spent on splits (only when rounds > 1).
    double splitReserve = 0.1;
    StageTwoOptions stage2;   ///< the engine's options (iterations is set per round) and device
};

/// @brief What fitToSamples() did.
struct VolumeFitReport {
    std::vector<StageTwoReport> rounds;
    std::size_t pruned = 0, split = 0;
    double msSplit = 0; ///< residual evaluation, prune and split
};

/// @brief Gaussians to start from when fitting in rounds: the budget less the split reserve.
std::size_t initialGaussianCount(std::size_t budget, const VolumeFitOptions& options);

/// @brief Fit `cloud` to the samples' targets (warped = rest positions, identity cells).
/// @param budget  most Gaussians the result may hold (splits never exceed it)
VolumeFitReport fitToSamples(GaussianCloud& cloud, const SampleSet& samples, std::size_t budget,
                             const VolumeFitOptions& options);

/// @brief Remove Gaussians with opacity below `alpha` (Stage II's prune); returns how many.
std::size_t pruneTransparent(GaussianCloud& cloud, float alpha);

/// @brief Split the `count` Gaussians with the largest residual mass into two each, by Stage II's
///        split with from-vdb's rule (stage2/Densify.h shrinkSplit(): +-0.5 sigma along the
///        widest axis, that axis' scale times 0.6, same opacity and SH).
/// @param residual [M] |O* - O| at the samples, each attributed to the nearest Gaussian centre
/// @return the number split
std::size_t splitLargestResidual(GaussianCloud& cloud, const SampleSet& samples, const std::vector<float>& residual,
                                 std::size_t count);

} // namespace splatwarp
