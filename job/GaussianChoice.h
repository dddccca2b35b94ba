#pragma once
/// @file GaussianChoice.h
/// @brief The keep's second step (StageTwoChoice.h): after the region mix, each Gaussian, heaviest
///        first, takes the candidate's version of it that lowers the validation score most. The
///        field is a plain sum over Gaussians, so swapping one changes the score only at the
///        validation points its old and new cutoff boxes reach, and that change is exact; a region
///        holds many Gaussians, and on captured models a few large ones hold most of the mass
///        (train-1000: 30 of 1,000 hold 87%), so one region's winner is often wrong for them.
#include <cstddef>
#include <vector>

#include "job/Judge.h"
#include "job/StageTwoChoice.h"
#include "core/GaussianCloud.h"

namespace splatwarp {

/// @brief What the per-Gaussian step did.
struct GaussianChoiceReport {
    std::size_t swapped = 0;  ///< Gaussians that took another candidate's version
    std::size_t tried = 0;    ///< Gaussians whose versions differ
    double before = 0, after = 0; ///< validation score (opacity + colour relative L1)
    double ms = 0;
};

/// @brief Refine `kept` (same Gaussians as every candidate): each Gaussian whose candidate
///        versions differ takes the one that lowers the validation score, heaviest (alpha times
///        its scales' product) first, in one pass. Picks that read the validation points on
///        opposite sides of one plane run on two threads between the picks that read both sides:
///        the same picks and sums as one at a time (the points' threaded flag).
GaussianCloud chooseEachGaussian(const Judge& validation, const std::vector<StageTwoCandidate>& candidates,
                                 GaussianCloud kept, GaussianChoiceReport& report);

} // namespace splatwarp
