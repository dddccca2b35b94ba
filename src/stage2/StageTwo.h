#pragma once
/// @file StageTwo.h
/// @brief Stage II: fit the moving Gaussians to the warped sampled field (paper
///        Sec. 3.2; choices: docs/design-notes.md). E = sum_j |F*_j - F(x_j)|_1 + lambda1 sum_j |O*_j - O(x_j)|
///        + lambda2 sum_{j: O*_j = 0} |O*_j - O(x_j)| over the samples not skipped, minimised by
///        Adam with analytic gradients.
#include <cstdint>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "core/GaussianCloud.h"
#include "field/SampleSet.h"
#include "stage2/StageTwoOptions.h"

namespace splatwarp {

/// @brief Energy at one iteration (before that iteration's step; the last entry is after the
///        final step). Terms are weighted, so total = color + opacity + boundary.
struct StageTwoEnergy {
    int iteration = 0;
    double total = 0, color = 0, opacity = 0, boundary = 0;
    bool rejected = false; ///< the step to this iterate was undone (StageTwoOptions::rejectSteps)
};

/// @brief What a Stage II run did.
struct StageTwoReport {
    Device device = Device::Cpu; ///< which device ran (in rounds: the last round's)
    std::vector<Device> roundDevices; ///< in rounds (stage2/Rounds.h): each round's device
    std::vector<StageTwoEnergy> energies;
    int bestIteration = 0;   ///< the iterate returned (the last accepted one; with neither rejectSteps nor keepBest the last)
    double bestEnergy = 0;   ///< its training energy
    int rejectedSteps = 0;   ///< steps undone by step rejection
    int stoppedAt = -1;      ///< iteration at which the run stopped early (StageTwoOptions::stallStop); -1: it ran to the end
    /// The held-out scores of StageTwoOptions::heldOutStop: (iteration, score), in order.
    std::vector<std::pair<int, double>> heldOutChecks;
    std::string stopReason;  ///< why it stopped early ("steps rejected in a row", "the energy stalled", "the validation score rose", "the validation score stays above the start's"); empty: it ran to the end
    std::size_t movingGaussians = 0;
    std::size_t samplesUsed = 0;    ///< samples in cells not skipped
    std::size_t samplesSkipped = 0;
    std::vector<std::uint64_t> pairsPerIteration; ///< counted (alpha*G >= cutoff) moving pairs per forward pass
    std::uint64_t coveragePairs = 0;              ///< candidate pairs of the last coverage
    int coverageRebuilds = 0;
    int coverageForcedRebuilds = 0;               ///< of those, rebuilds because a Gaussian left its coverage early
    float sceneExtent = 0;                        ///< multiplies the position learning rate
    std::uint64_t gpuPeakBytes = 0;               ///< CUDA: peak GPU memory of the run's buffers (not the context); CPU: 0
    // Time per phase in milliseconds.
    double msSetup = 0, msCoverage = 0, msForward = 0, msBackward = 0, msUpdate = 0, msTotal = 0;
    /// Of msForward + msBackward: the passes that evaluated a step the run then rejected (redone
    /// from the kept iterate at a lower rate: work lost).
    double msRejected = 0;
};

/// @brief Host bytes Stage II adds per sample (positions, static and gradient features, energies,
///        pair counts), for the memory estimates made before a sample set is allocated.
std::size_t stageTwoBytesPerSample(int shDegree);

/// @brief Run Stage II.
/// @param cloud         in: the Stage I result; out: the fitted model (static Gaussians bit-exact)
/// @param samples       the warped sampled field (targets, warped positions, cells)
/// @param moving        [N] 1: optimise this Gaussian; 0: keep it (it still contributes)
/// @param gaussianCell  [N] rest cell of each Gaussian (index into samples' cells) for its
///                      low-pass filter; -1: no filter for that Gaussian
/// @param onEval        called with (iteration, cloud) after every evalEvery-th step (0: never)
/// @throws InputError when array sizes disagree or the SH degrees differ
StageTwoReport optimiseStageTwo(GaussianCloud& cloud, const SampleSet& samples, const std::vector<std::uint8_t>& moving,
                                const std::vector<std::int32_t>& gaussianCell, const StageTwoOptions& options,
                                const std::function<void(int, const GaussianCloud&)>& onEval = {},
                                int evalEvery = 0);

} // namespace splatwarp
