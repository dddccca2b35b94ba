#pragma once
/// @file StageTwoRounds.h
/// @brief deform's Stage II with --split: two rounds of the one round loop (stage2/Rounds.h) with
///        the split of stretched cells (and the prune) between them.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <functional>
#include <string>
#include <vector>

#include "core/GaussianCloud.h"
#include "field/SampleSet.h"
#include "stage2/Densify.h"
#include "stage2/Rounds.h"
#include "stage2/StageTwo.h"

namespace splatwarp {

/// @brief Split and prune in Stage II (src/stage2/Densify.h): with a split, Stage II runs in two
///        rounds (one runStageTwo() call each, so every device follows) with the split between them.
struct DensifyJobOptions {
    bool split = false;         ///< --split auto: split the moving Gaussians of stretched cells
    float splitStretch = 1.3f;  ///< a cell is stretched when its F's largest singular value is above this
    float splitAfter = 0.5f;    ///< share of the iterations before the split (0: split before Stage II)
    float splitOffset = kSplitOffset; ///< children at mean +- this x sigma along the longest axis
    float pruneBelow = 0.0f;    ///< remove moving Gaussians whose opacity ends below this (0: none)
    /// With split: at most this many Gaussians split (each adds one), the first stretched ones
    /// in index order; none: no limit (`--max-gaussians`).
    std::optional<std::size_t> maxSplits;
};

/// @brief Gaussians split and pruned by a Stage II run, and the time it took.
struct DensifyCounts {
    std::size_t split = 0, pruned = 0;
    double ms = 0;
};

/// @brief Stage II in rounds: the iterations before the split, split (and prune) on the host, the
///        rest; one round when splitting is off. Children inherit their parent's moving flag and cell.
///        The report's roundDevices lists the device of each round.
/// @param onEval          sees each round's iterations offset by the iterations before it
/// @param dropEvalsAfter  called with an offset when a round fell back from the GPU to the CPU
///                        after onEval saw some of its iterations: drop those after the offset
///                        (the CPU run evaluates them again)
StageTwoReport fitInRounds(GaussianCloud& fitted, const SampleSet& samples, const std::vector<std::uint8_t>& moving,
                           const std::vector<std::int32_t>& gaussianCell, const StageTwoOptions& options,
                           const DensifyJobOptions& densify, const std::function<void(int, const GaussianCloud&)>& onEval,
                           int evalEvery, DensifyCounts& counts, const std::function<void(int)>& dropEvalsAfter = {});

} // namespace splatwarp
