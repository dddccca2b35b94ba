#pragma once
/// @file StageTwoChoice.h
/// @brief Stage II fits a low-pass filtered field; where the Gaussians are far thinner than its
///        filter (captured models) the fit can make the unfiltered field worse than its start.
///        The choice judges its candidates (the start, the curve-shifted start, the fit) on
///        validation points (the judge's rule with another seed, so never the judge's points) per
///        region of a coarse lattice in the deformed space; each mix of two or more takes every
///        Gaussian from the one that wins its region, and the candidate or mix the validation
///        points judge best is returned.
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "job/Judge.h"
#include "core/GaussianCloud.h"
#include "stage2/StageTwo.h"

namespace splatwarp {

/// Seed of the validation points: the judge's seed XOR this (a fixed, different point set).
constexpr std::uint32_t kValidationSeedXor = 0x5bd1e995u;

/// Regions along the validation points' largest warped extent.
constexpr int kChoiceRegions = 16;

/// @brief The selector's rule, shared by every choice the validation points make (the curve split
///        with fans or without, the curve shift's share, the keep's candidates): each model's
///        validation score (opacity + colour relative L1, Judge::score()) and the first lowest.
struct Selection {
    std::size_t best = 0;
    std::vector<double> scores;
};

/// @brief The first lowest of `scores` (its index; 0 when empty).
std::size_t firstLowest(const std::vector<double>& scores);

/// @brief Score each model on the validation points and pick the first lowest.
Selection selectBest(const Judge& validation, const std::vector<const GaussianCloud*>& models);

/// @brief A model the choice may keep: Stage II's start, its fit, or another start.
struct StageTwoCandidate {
    std::string name;
    const GaussianCloud* model = nullptr;
};

/// @brief Which model the choice kept and the validation scores (opacity + colour relative L1).
struct StageTwoChoice {
    std::string kept; ///< a candidate's name or "mix"
    std::vector<double> scores;          ///< per candidate
    std::vector<std::size_t> regionsWon; ///< per candidate: the regions the best mix takes from it
    std::string mixOf;                   ///< the candidates of the best mix, "start+fit"
    double mix = 0;                      ///< its score (infinite when none could mix)
    std::size_t regions = 0; ///< regions with validation points
    double ms = 0;
};

/// @brief Choose among Stage II's candidates (see the file comment); the first one's means place
///        the Gaussians in regions. `sameGaussians`: Gaussian i is the same one in every candidate
///        (no split or prune inside Stage II), so they can mix.
GaussianCloud chooseStageTwoModel(const Judge& validation, const std::vector<StageTwoCandidate>& candidates,
                                  bool sameGaussians, StageTwoChoice& report);

/// How far below Stage II's last validation check its fit must end for deform to say it was still
/// improving: the donut fell 5.4% over its last 10 of 50 iterations and 50 more bought it 6-8% on
/// the judge; every other row measured fell 3.1% or less, or stopped (docs/lab/stage2-iterations.md).
constexpr double kStillImproving = 0.04;

/// @brief The fall of the validation score from Stage II's last check (at iteration > 0) to its
///        fit (`fitScore`, at the end), as a share of the check's, when the run ran all its
///        iterations and the fall is kStillImproving or more; 0 otherwise.
double stillImprovingBy(const StageTwoReport& fit, double fitScore);

/// Shares of the curve shift --curve-shift auto tries (deform/CurveSplit.h curveShifted()).
constexpr double kCurveShares[] = {0.25, 0.5, 0.75, 1.0};

/// @brief The curve shift the validation points judge best.
struct CurveShiftChoice {
    double share = 0.0;
    GaussianCloud model;      ///< start shifted by share
    std::vector<double> scores; ///< per share tried
    double ms = 0;
};

/// @brief The share (of `shares`) whose shifted start the validation points score lowest.
CurveShiftChoice chooseCurveShift(const Judge& validation, const GaussianCloud& start, const std::vector<float>& curve,
                                  const std::vector<double>& shares);

} // namespace splatwarp
