#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "ChoiceFixture.h"
#include "job/StageTwoChoice.h"
#include "deform/CurveSplit.h"

using namespace splatwarp;
using namespace splatwarp::test;

// Start and fit each wrong on one half: the mix takes each region from the side that is right
// there, and is far better than either.
TEST(StageTwoChoice, TheMixTakesEachRegionFromTheSideThatFitsIt)
{
    const ChoiceFixture fx;
    const GaussianCloud start = fx.blanked(true), fit = fx.blanked(false);
    StageTwoChoice c;
    const GaussianCloud kept = chooseStageTwoModel(*fx.validation, {{"start", &start}, {"fit", &fit}}, true, c);
    EXPECT_EQ(c.kept, "mix");
    // Measured: start 1.169, fit 1.138, mix 0.327, Stage I itself 0.314 (the regions astride the
    // median keep one blank half); the fit won 256 of 704 regions.
    ASSERT_EQ(c.scores.size(), 2u);
    EXPECT_LT(c.mix, 0.5 * std::min(c.scores[0], c.scores[1])) << c.scores[0] << " " << c.scores[1] << " " << c.mix;
    EXPECT_LT(c.mix, 1.1 * fx.validation->score(fx.stage1));
    EXPECT_NEAR(fx.validation->score(kept), c.mix, 1e-12);
    EXPECT_GT(c.regionsWon[1], 0u);
    EXPECT_LT(c.regionsWon[1], c.regions);
    EXPECT_EQ(c.regionsWon[0] + c.regionsWon[1], c.regions);
    // Gaussians that are not the same ones on both sides never mix.
    StageTwoChoice d;
    chooseStageTwoModel(*fx.validation, {{"start", &start}, {"fit", &fit}}, false, d);
    EXPECT_NE(d.kept, "mix");
}

// Three candidates, each right on one third of the deformed x range only: the mix takes each
// region from the one right there.
TEST(StageTwoChoice, TheMixTakesEachRegionFromTheBestOfThreeCandidates)
{
    const ChoiceFixture fx;
    std::vector<float> xs;
    for (std::size_t i = 0; i < fx.stage1.size(); ++i) xs.push_back(fx.stage1.mean(i).x);
    std::sort(xs.begin(), xs.end());
    const float cut[2] = {xs[xs.size() / 3], xs[2 * xs.size() / 3]};
    auto rightOnly = [&](int third) { // blank every Gaussian outside one third
        GaussianCloud g = fx.stage1;
        for (std::size_t i = 0; i < g.size(); ++i) {
            const float x = g.mean(i).x;
            const int t = x < cut[0] ? 0 : (x < cut[1] ? 1 : 2);
            if (t != third) g.opacities[i] = -30.0f;
        }
        return g;
    };
    const GaussianCloud a = rightOnly(0), b = rightOnly(1), f = rightOnly(2);
    StageTwoChoice c;
    const GaussianCloud kept = chooseStageTwoModel(*fx.validation, {{"a", &a}, {"b", &b}, {"fit", &f}}, true, c);
    EXPECT_EQ(c.kept, "mix");
    ASSERT_EQ(c.regionsWon.size(), 3u);
    for (std::size_t won : c.regionsWon) EXPECT_GT(won, 0u);
    const double stage1 = fx.validation->score(fx.stage1);
    // Each one alone misses two thirds; the mix loses only the regions astride the two cuts.
    for (double s : c.scores) EXPECT_GT(s, 2.0 * stage1) << s;
    EXPECT_LT(c.mix, 1.2 * stage1) << c.mix << " against Stage I " << stage1;
    // Measured: alone 1.411 / 1.467 / 1.414, the mix of all three 0.371, Stage I 0.314. A mix of
    // two leaves a third blank, so the widest mix is the best here.
    EXPECT_EQ(c.mixOf, "a+b+fit");
    EXPECT_NEAR(fx.validation->score(kept), c.mix, 1e-12);
}

// A fit worse everywhere is dropped for its start (the mix takes every region from the start:
// it is the start, not below it).
TEST(StageTwoChoice, AFitWorseThanItsStartIsDropped)
{
    const ChoiceFixture fx;
    StageTwoChoice c;
    const GaussianCloud blank = fx.blanked(true);
    const GaussianCloud kept = chooseStageTwoModel(*fx.validation, {{"start", &fx.stage1}, {"fit", &blank}}, true, c);
    EXPECT_EQ(c.kept, "start");
    EXPECT_EQ(kept.opacities, fx.stage1.opacities);
    EXPECT_LT(c.scores[0], c.scores[1]);
    StageTwoChoice d;
    chooseStageTwoModel(*fx.validation, {{"start", &blank}, {"fit", &fx.stage1}}, true, d);
    EXPECT_EQ(d.kept, "fit");
}

// The curve shift keeps the share whose shifted start scores lowest on the validation points, and
// that model is the start with every mean moved by the share of its second-order offset.
TEST(StageTwoChoice, TheCurveShiftTakesTheShareTheValidationPointsPrefer)
{
    const ChoiceFixture fx;
    const StageOneResult s1 = fx.rest->stageOne->apply(fx.deformation.transforms, fx.deformation.nodeMoving);
    const std::vector<float> curve = stageOneBendingOf(fx.rest->model, fx.rest->rig, fx.rest->graph,
                                                       fx.deformation.transforms, s1.deformed, s1.moving, {})
                                         .curve;
    const std::vector<double> shares{0.0, 0.5, 1.0, 2.0};
    const CurveShiftChoice c = chooseCurveShift(*fx.validation, fx.stage1, curve, shares);
    ASSERT_EQ(c.scores.size(), shares.size());
    EXPECT_EQ(c.scores[0], fx.validation->score(fx.stage1)); // share 0 is the start
    for (double s : c.scores) EXPECT_GE(s, fx.validation->score(c.model));
    const GaussianCloud expected = curveShifted(fx.stage1, curve, c.share);
    EXPECT_EQ(c.model.means, expected.means);
    EXPECT_EQ(c.model.opacities, fx.stage1.opacities);
    // The stripes bend moves mass off the skinned centres: a share of the offset judges better
    // than none, and twice the offset overshoots (measured, shares 0 / 0.5 / 1 / 2: 0.314 / 0.229 /
    // 0.267 / 0.486).
    EXPECT_GT(c.share, 0.0);
    EXPECT_LT(c.scores[1], 0.9 * c.scores[0]);
    EXPECT_GT(c.scores[3], c.scores[1]);
}

// The selector's rule: each model's validation score, the first lowest kept (ties go to the earlier).
TEST(StageTwoChoice, TheSelectorKeepsTheFirstLowestScore)
{
    EXPECT_EQ(firstLowest({3.0, 1.0, 1.0, 2.0}), 1u);
    EXPECT_EQ(firstLowest({}), 0u);
    const ChoiceFixture fx;
    const GaussianCloud blanked = fx.blanked(true);
    const Selection s = selectBest(*fx.validation, {&blanked, &fx.stage1, &fx.stage1});
    ASSERT_EQ(s.scores.size(), 3u);
    EXPECT_EQ(s.best, 1u);
    EXPECT_EQ(s.scores[1], fx.validation->score(fx.stage1));
    EXPECT_GT(s.scores[0], s.scores[1]);
}

// deform advises more iterations only when the run ran to its end and its fit ended well below the
// last check (kStillImproving of it), never from the start's check alone.
TEST(StageTwoChoice, AFitStillImprovingAtItsEndIsSaidOnlyWhenItFellEnough)
{
    StageTwoReport fit;
    fit.heldOutChecks = {{0, 0.108}, {10, 0.068}, {40, 0.04}};
    const double justPast = 0.04 * (1.0 - kStillImproving) - 1e-9;
    EXPECT_NEAR(stillImprovingBy(fit, 0.0378), 0.055, 1e-12);
    EXPECT_NEAR(stillImprovingBy(fit, justPast), kStillImproving, 1e-7);
    EXPECT_EQ(stillImprovingBy(fit, 0.04 * (1.0 - 0.5 * kStillImproving)), 0.0); // a small fall
    EXPECT_EQ(stillImprovingBy(fit, 0.041), 0.0);                               // a rise
    EXPECT_EQ(stillImprovingBy(fit, std::nan("")), 0.0);

    StageTwoReport stopped = fit; // the validation stop ended it: the fit got worse
    stopped.stoppedAt = 40;
    EXPECT_EQ(stillImprovingBy(stopped, 0.0378), 0.0);

    StageTwoReport startOnly; // one check (the start's) says nothing of the run's end
    startOnly.heldOutChecks = {{0, 0.108}};
    EXPECT_EQ(stillImprovingBy(startOnly, 0.03), 0.0);
    EXPECT_EQ(stillImprovingBy(StageTwoReport(), 0.03), 0.0);
}
