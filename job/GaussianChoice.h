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

/// A Gaussian takes another version only where its versions reach at least this many validation
/// points: on fewer, the change measured is mostly which points happened to fall there. Stripes of
/// 200k Gaussians (10 draws, 79k points) swapped 107k Gaussians that way, and a 2M-point judge rose
/// 0.0193 -> 0.0268 over the region mix they were taken from; with 8, 1.6k swapped and 0.0193.
/// Captured models gain 1-2% (guitar, playbot-31k), the others move by 0.3% or less
/// (docs/lab/choice-points.md).
constexpr std::size_t kMinChoicePoints = 8;

/// @brief What the per-Gaussian step did.
struct GaussianChoiceReport {
    std::size_t swapped = 0;  ///< Gaussians that took another candidate's version
    std::size_t tried = 0;    ///< Gaussians whose versions differ
    std::size_t held = 0;     ///< Gaussians a version measured on fewer than kMinChoicePoints points would have lowered
    double before = 0, after = 0; ///< validation score (opacity + colour relative L1)
    double ms = 0;
};

/// @brief Refine `kept` (same Gaussians as every candidate): each Gaussian whose candidate
///        versions differ takes the one that lowers the validation score most, among those whose
///        change reaches at least kMinChoicePoints points, heaviest (alpha times its scales'
///        product) first, in one pass. Picks that read the validation points on
///        opposite sides of one plane run on two threads between the picks that read both sides:
///        the same picks and sums as one at a time (the points' threaded flag).
GaussianCloud chooseEachGaussian(const Judge& validation, const std::vector<StageTwoCandidate>& candidates,
                                 GaussianCloud kept, GaussianChoiceReport& report);

} // namespace splatwarp
