#pragma once
/// @file Selector.h
/// @brief The deform pipeline's one selector: every choice between candidate models is made on its
///        validation points (the judge's rule with other seeds, so never the judge's points), by
///        one rule (the lower opacity + colour relative L1 wins, the first on a tie), in one of
///        three modes:
///        - best: one model of several (the curve split with fans or without, the curve shift's
///          share, the keep's candidates);
///        - region mix: each region of a coarse lattice takes the candidate that wins it
///          (StageTwoChoice.h);
///        - per Gaussian: each Gaussian takes the candidate's version that lowers the score
///          (GaussianChoice.h).
///        The validated split (ValidatedSplit.h) measures its splits on the same points.
#include <vector>

#include "core/GaussianCloud.h"
#include "job/GaussianChoice.h"
#include "job/Judge.h"
#include "job/StageTwoChoice.h"

namespace splatwarp {

class Selector {
public:
    /// @param validationRest the validation points' rest side (prepareValidationRest())
    Selector(const GaussianCloud& restModel, const JudgeRest& validationRest, const Deformation& deformation,
             bool threaded = true)
        : mPoints(restModel, validationRest, deformation, threaded)
    {
        mPoints.rememberEvaluations(kRememberedBytes);
    }

    /// Evaluations kept for scoring a model again: on guitar (SH 0, 200k points) the keep's
    /// candidates were evaluated 2-10 models earlier, 3.2 MB each.
    static constexpr std::size_t kRememberedBytes = std::size_t(32) << 20;

    /// @brief A model's validation score (opacity + colour relative L1; lower is better).
    double score(const GaussianCloud& model) const { return mPoints.score(model); }

    /// @brief Forget the last model scored (Judge::forgetLatest()).
    void forgetLatest() { mPoints.forgetLatest(); }

    /// @brief Best: each model's score and the first lowest.
    Selection best(const std::vector<const GaussianCloud*>& models) const { return selectBest(mPoints, models); }

    /// @brief Best among the start shifted by each share (made one at a time: one shifted model is
    ///        held at once).
    CurveShiftChoice bestCurveShift(const GaussianCloud& start, const std::vector<float>& curve,
                                    const std::vector<double>& shares) const
    {
        return chooseCurveShift(mPoints, start, curve, shares);
    }

    /// @brief Best of the candidates and of their region mixes (`sameGaussians`: they can mix).
    GaussianCloud regionMix(const std::vector<StageTwoCandidate>& candidates, bool sameGaussians,
                            StageTwoChoice& report) const
    {
        return chooseStageTwoModel(mPoints, candidates, sameGaussians, report);
    }

    /// @brief `kept` with each Gaussian, heaviest first, in the candidate's version that lowers
    ///        the score.
    GaussianCloud perGaussian(const std::vector<StageTwoCandidate>& candidates, GaussianCloud kept,
                              GaussianChoiceReport& report) const
    {
        return chooseEachGaussian(mPoints, candidates, std::move(kept), report);
    }

    /// @brief The points themselves (the validated split's exact score changes).
    const Judge& points() const { return mPoints; }

private:
    Judge mPoints;
};

} // namespace splatwarp
