#pragma once
/// @file ValidatedSplit.h
/// @brief Split the Gaussians whose split the validation points measure to pay. The curve split
///        (deform/CurveSplit.h) predicts the gain from phi's second-order term at +-2 sigma; on
///        captured scenes a few large Gaussians hold most of the mass and of Stage I's error while
///        that term stays small there (train-1000: half the error on 3 of 1,000). Here every
///        unsplit moving Gaussian is split in three along each of its axes in the rest pose (the
///        curve split's L1-closest pattern), the children are moved by Stage I, and the exact
///        change of the validation score (ValidationResiduals.h) decides: the largest drops first,
///        each re-measured against the swaps already made, within a budget.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "job/Judge.h"
#include "stage2/Densify.h"
#include "core/GaussianCloud.h"
#include "deform/Deformation.h"
#include "deform/StageOne.h"

namespace splatwarp {

/// A split is kept when it lowers the validation score by more than this share of the score.
constexpr double kValidatedSplitMinGain = 1e-4;
/// At most this many Gaussians, the heaviest, are tried: their nine children are held at once
/// (about 140 MB at SH degree 3).
constexpr std::size_t kValidatedSplitMaxTried = 65536;

/// @brief What the validated split did.
struct ValidatedSplitReport {
    std::size_t tried = 0, split = 0, added = 0; ///< tried: 0 when the budget is spent
    double before = 0, after = 0; ///< validation score (0 when nothing was tried)
    double ms = 0;
};

/// @brief Split (see the file comment) the Gaussians i < rest.size() of `start` that are still
///        Stage I's (equal to stage1Deformed's i; the kValidatedSplitMaxTried heaviest), adding at
///        most `budget` Gaussians. `start` is Stage II's start (its curve rows kept when it has them),
///        changed in place.
ValidatedSplitReport validatedSplit(const Judge& validation, const GaussianCloud& rest, const Deformation& deformation,
                                    const StageOneOptions& stage1, const GaussianCloud& stage1Deformed,
                                    std::size_t budget, FitState start);

} // namespace splatwarp
