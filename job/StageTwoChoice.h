#pragma once
/// @file StageTwoChoice.h
/// @brief Stage II fits a low-pass filtered field; where the Gaussians are far thinner than its
///        filter (captured models) the fit can make the unfiltered field worse than its start.
///        The choice judges the start and the fit on validation points (the judge's rule with
///        another seed, so never the judge's points) per region of a coarse lattice in the
///        deformed space, keeps each Gaussian from the side that wins its region, and returns
///        whichever of start, fit and that mix the validation points judge best.
#include <cstddef>
#include <cstdint>
#include <string>

#include "Judge.h"
#include "core/GaussianCloud.h"

namespace splatwarp {

/// Seed of the validation points: the judge's seed XOR this (a fixed, different point set).
constexpr std::uint32_t kValidationSeedXor = 0x5bd1e995u;

/// Regions along the validation points' largest warped extent.
constexpr int kChoiceRegions = 16;

/// @brief Which model the choice kept and the validation scores (opacity + colour relative L1).
struct StageTwoChoice {
    std::string kept = "fit"; ///< "start", "fit" or "mix"
    double start = 0, fit = 0, mix = 0;
    std::size_t regions = 0, regionsFit = 0; ///< regions with validation points, those where the fit won
    double ms = 0;
};

/// @brief Choose between Stage II's start and fit (see the file comment). `sameGaussians`: Gaussian
///        i of the fit is Gaussian i of the start (no split or prune inside Stage II), so they can mix.
GaussianCloud chooseStageTwoModel(const Judge& validation, const GaussianCloud& start, GaussianCloud fit,
                                  bool sameGaussians, StageTwoChoice& report);

} // namespace splatwarp
