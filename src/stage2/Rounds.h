#pragma once
/// @file Rounds.h
/// @brief Stage II in rounds with a host step between them: the one round loop of `deform --split`
///        (split and prune between two rounds, job/StageTwoRounds.h) and of `from-vdb --rounds`
///        (prune and split by residual, fit/VolumeFit.h). Each round is one runStageTwo() call on a
///        fresh solver, so the CPU and CUDA solvers follow the same rules.
#include <functional>
#include <string>
#include <vector>

#include "field/SampleSet.h"
#include "stage2/Densify.h"
#include "stage2/StageTwo.h"

namespace splatwarp {

/// @brief The rounds of a fit and what runs between them.
struct RoundsPlan {
    std::vector<int> iterations; ///< per round; a round of 0 iterations is not run (its between step is)
    /// Run the last round even with 0 iterations when no round ran (deform: its report always has a fit).
    bool atLeastOne = false;
    /// After each round but the last, on the state (split, prune); sees the round's index.
    std::function<void(int round)> between;
    std::function<void(int, const GaussianCloud&)> onEval; ///< sees iterations offset by the rounds before
    int evalEvery = 0;
    /// Called with an offset when a round fell back from the GPU to the CPU after onEval saw some of
    /// its iterations: drop those after the offset (the CPU run evaluates them again).
    std::function<void(int)> dropEvalsAfter;
};

/// @brief Each round's report and all of them as one: energies, pairs and iterations offset by the
///        iterations before, counters and times summed, each round's device in roundDevices, the
///        rest (best iterate, moving count, device) of the last round.
struct RoundsReport {
    std::vector<StageTwoReport> rounds;
    StageTwoReport merged;
};

/// @brief Fit the state's cloud to the samples in the plan's rounds (options.iterations is replaced
///        by each round's count).
RoundsReport fitRounds(FitState& state, const SampleSet& samples, const StageTwoOptions& options, const RoundsPlan& plan);

/// @brief The device(s) of a run: "cpu" or "cuda", or each round's in order when they differ
///        ("cuda+cpu": the second round fell back to the CPU).
std::string devicesName(const StageTwoReport& report);

} // namespace splatwarp
