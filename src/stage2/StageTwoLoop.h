#pragma once
/// @file StageTwoLoop.h
/// @brief The one Stage II optimisation loop, over any StageTwoSolver: coverage schedule and
///        the every-iteration holds check, energies and progress, best-iterate keeping, the
///        held-out evaluation callback and the report.
#include <functional>

#include "stage2/StageTwoSolver.h"

namespace splatwarp {

using StageTwoEval = std::function<void(int, const GaussianCloud&)>;

/// @brief Run options.iterations Adam steps of a solver and write the result into cloud (the
///        cloud the solver was set up from; only its moving Gaussians change).
/// @param onEval  called with (iteration, current model) after every evalEvery-th step (0: never)
/// @throws InputError when the energy at the start is not finite (NaN/Inf in model or targets)
StageTwoReport runStageTwoLoop(StageTwoSolver& solver, GaussianCloud& cloud, const StageTwoOptions& options,
                               const StageTwoEval& onEval = {}, int evalEvery = 0);

} // namespace splatwarp
