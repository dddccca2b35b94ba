#pragma once
/// @file CpuSolver.h
/// @brief The CPU Stage II solver (oneTBB): samples in padded blocks (SampleBlocks.h), coverage
///        between blocks and Gaussians, the pair work vectorised over a block's samples
///        (BlockLoops.h). Forward per block (each sample sums its Gaussians in ascending
///        order), backward per Gaussian (its blocks in ascending order): deterministic for any
///        thread count.
#include <memory>

#include "stage2/StageTwoSolver.h"

namespace splatwarp {

/// @brief Set up the CPU solver for a run (validates the inputs like optimiseStageTwo()).
std::unique_ptr<StageTwoSolver> makeCpuStageTwoSolver(const GaussianCloud& cloud, const SampleSet& samples,
                                                      const std::vector<std::uint8_t>& moving,
                                                      const std::vector<std::int32_t>& gaussianCell,
                                                      const StageTwoOptions& options);

/// @brief What one forward and backward pass computes at the start parameters (fresh coverage),
///        for tests against a double-precision reference. S used samples, G moving Gaussians.
struct StageTwoProbe {
    std::vector<std::uint32_t> used, moving; ///< [S], [G]
    std::vector<float> features, opacity;    ///< [S,stride], [S]
    std::vector<float> gradF, gradO;         ///< [S,stride], [S] dE/dF, dE/dO
    std::vector<float> grad;                 ///< [G, 11+stride] packed dE/dparameters (StageTwoParams.h)
    StageTwoEnergy energy;
    std::uint64_t pairs = 0;
};

/// @brief Run the CPU probe (the cloud is not changed).
StageTwoProbe probeCpuStageTwo(const GaussianCloud& cloud, const SampleSet& samples, const std::vector<std::uint8_t>& moving,
                               const std::vector<std::int32_t>& gaussianCell, const StageTwoOptions& options);

} // namespace splatwarp
