#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "ChoiceFixture.h"
#include "job/GaussianChoice.h"
#include "job/ValidatedSplit.h"
#include "job/ValidationResiduals.h"
#include "deform/CurveSplit.h"

using namespace splatwarp;
using namespace splatwarp::test;

namespace {

/// Stage I's model with every Gaussian of one index parity made invisible.
GaussianCloud blankedParity(const GaussianCloud& g, int parity)
{
    GaussianCloud out = g;
    for (std::size_t i = std::size_t(parity); i < out.size(); i += 2) out.opacities[i] = -30.0f;
    return out;
}

/// A judge of the fixture's deformation on the thinned, weighted validation points.
std::unique_ptr<Judge> weightedJudge(const ChoiceFixture& fx, std::size_t points, std::uint32_t seed)
{
    HeldOutOptions h;
    h.points = points;
    h.seed = seed;
    return std::make_unique<Judge>(fx.rest->model, prepareValidationRest(fx.rest->model, h), fx.deformation);
}

/// `g` with every Gaussian but i made invisible.
GaussianCloud onlyGaussian(const GaussianCloud& g, std::size_t i)
{
    GaussianCloud out = g;
    for (std::size_t j = 0; j < out.size(); ++j)
        if (j != i) out.opacities[j] = -30.0f;
    return out;
}

} // namespace

// The points a swap changes are those where the old or the new version has weight: counted
// against the judge's own evaluation of each version alone.
TEST(ValidationResiduals, ChangesCountThePointsEitherVersionReaches)
{
    const ChoiceFixture fx;
    GaussianCloud other = fx.stage1;
    const Vec3f m = other.mean(7);
    other.setMean(7, Vec3f{m.x + 2.0f * other.scale(7).x, m.y, m.z});
    other.logScales[3 * 11] -= 2.0f; // Gaussian 11 thinner along x
    ValidationResiduals r(*fx.validation, fx.stage1);
    for (std::size_t i : {std::size_t(7), std::size_t(11)}) {
        double change = 0;
        std::size_t points = 0;
        r.changes({{&fx.stage1, i}}, {{{&other, i}}}, &change, &points);
        const auto a = fx.validation->evaluate(onlyGaussian(fx.stage1, i));
        const auto b = fx.validation->evaluate(onlyGaussian(other, i));
        std::size_t reached = 0;
        for (std::size_t p = 0; p < a->opacity.size(); ++p) reached += a->opacity[p] > 0.0f || b->opacity[p] > 0.0f;
        EXPECT_GT(reached, 0u);
        EXPECT_EQ(points, reached) << "Gaussian " << i;
    }
}

// The residuals' score change for a swap (one Gaussian moved, one split in three) is the
// difference of the two models' validation scores, on plain and on weighted points.
TEST(ValidationResiduals, AChangeIsTheDifferenceOfTheScores)
{
    const ChoiceFixture fx;
    const std::unique_ptr<Judge> weighted = weightedJudge(fx, 20000, 3);
    for (const Judge* judge : {fx.validation.get(), weighted.get()}) {
        ValidationResiduals r(*judge, fx.stage1);
        const double s0 = judge->score(fx.stage1);
        EXPECT_NEAR(r.score(), s0, 1e-6 * s0);
        // Gaussian 7 moved by a sigma along x and brightened.
        GaussianCloud moved = fx.stage1;
        const Vec3f m = moved.mean(7);
        moved.setMean(7, Vec3f{m.x + moved.scale(7).x, m.y, m.z});
        moved.opacities[7] += 1.0f;
        const double d = r.change({{&fx.stage1, 7}}, {{&moved, 7}});
        EXPECT_NE(d, 0.0);
        EXPECT_NEAR(d, judge->score(moved) - s0, 1e-6 * s0);
        // Gaussian 11 replaced by its three curve-split children (appended).
        GaussianCloud split = fx.stage1;
        GaussianCloud children;
        children.shDegree = split.shDegree;
        appendSplitChildren(fx.stage1, 11, 0, curveSplitPattern(0.0, 0.0), children);
        split.assign(11, children, 0);
        split.append(children, 1);
        split.append(children, 2);
        const double e = r.change({{&fx.stage1, 11}}, {{&children, 0}, {&children, 1}, {&children, 2}});
        EXPECT_NEAR(e, judge->score(split) - s0, 1e-6 * s0);
        r.apply({{&fx.stage1, 11}}, {{&children, 0}, {&children, 1}, {&children, 2}});
        EXPECT_NEAR(r.score(), judge->score(split), 1e-6 * s0);
    }
}

// The weighted validation points estimate the judge's score with many more points inside the
// model than the judge's count: kept about (1.6 + 0.4) x the points, deterministic for a seed.
TEST(ValidationResiduals, WeightedPointsEstimateTheJudgesScore)
{
    const ChoiceFixture fx;
    const JudgeRest a = prepareValidationRest(fx.rest->model, {20000, 3});
    const JudgeRest b = prepareValidationRest(fx.rest->model, {20000, 3});
    EXPECT_EQ(a.points.rest, b.points.rest);
    EXPECT_EQ(a.unrotated.weight, b.unrotated.weight);
    std::size_t inside = 0;
    for (float o : a.unrotated.opacity) inside += o > 0.0f;
    EXPECT_NEAR(double(inside), kValidationInside * 20000, 0.1 * kValidationInside * 20000);
    EXPECT_NEAR(double(a.points.size() - inside), kValidationOutside * 20000, 0.1 * kValidationOutside * 20000);
    // Against the judge's rule with 10x the points (another seed), Stage I and a blanked half.
    HeldOutOptions many;
    many.points = 200000;
    many.seed = 99;
    const Judge reference(fx.rest->model, prepareJudgeRest(fx.rest->model, many), fx.deformation);
    const Judge weighted(fx.rest->model, a, fx.deformation);
    for (const GaussianCloud& g : {fx.stage1, fx.blanked(true)}) {
        const double w = weighted.score(g), ref = reference.score(g);
        EXPECT_NEAR(w, ref, 0.05 * ref) << w << " against " << ref;
    }
}

// Start and fit each blank every other Gaussian: every region holds both kinds, so the region mix
// cannot help, while the per-Gaussian step takes each Gaussian from the side where it is visible
// and gets Stage I's model back.
TEST(GaussianChoice, EachGaussianTakesTheVersionThatLowersTheScore)
{
    const ChoiceFixture fx;
    const GaussianCloud start = blankedParity(fx.stage1, 0), fit = blankedParity(fx.stage1, 1);
    const std::vector<StageTwoCandidate> candidates{{"start", &start}, {"fit", &fit}};
    StageTwoChoice c;
    const GaussianCloud mix = chooseStageTwoModel(*fx.validation, candidates, true, c);
    GaussianChoiceReport r;
    const GaussianCloud kept = chooseEachGaussian(*fx.validation, candidates, mix, r);
    const double stage1 = fx.validation->score(fx.stage1);
    EXPECT_GT(fx.validation->score(mix), 1.5 * stage1);
    EXPECT_NEAR(fx.validation->score(kept), r.after, 1e-6 * stage1);
    EXPECT_NEAR(r.before, fx.validation->score(mix), 1e-6 * stage1);
    EXPECT_LT(r.after, 1.01 * stage1) << r.after << " against Stage I " << stage1;
    EXPECT_EQ(r.tried, fx.stage1.size());
    EXPECT_GT(r.swapped, fx.stage1.size() / 4);
    // The swaps are whole Gaussians of the candidates.
    std::size_t fromStage1 = 0;
    for (std::size_t i = 0; i < kept.size(); ++i) fromStage1 += kept.opacities[i] == fx.stage1.opacities[i];
    EXPECT_GT(fromStage1, 9 * kept.size() / 10);
}

// On too few validation points the same candidates are mostly held back: a Gaussian takes another
// version only where the change reaches kMinChoicePoints points, which every swap does.
TEST(GaussianChoice, AVersionMeasuredOnTooFewPointsIsNotTaken)
{
    const ChoiceFixture fx;
    HeldOutOptions h;
    h.points = 3000;
    h.seed = 7;
    const Judge sparse(fx.rest->model, prepareJudgeRest(fx.rest->model, h), fx.deformation);
    const GaussianCloud start = blankedParity(fx.stage1, 0), fit = blankedParity(fx.stage1, 1);
    const std::vector<StageTwoCandidate> candidates{{"start", &start}, {"fit", &fit}};
    GaussianChoiceReport r;
    const GaussianCloud kept = chooseEachGaussian(sparse, candidates, start, r);
    EXPECT_GT(r.held, r.tried / 4) << r.swapped;
    EXPECT_GT(r.swapped, 0u);
    EXPECT_LE(r.swapped + r.held, r.tried);
    // Each swap, undone alone on the kept model, reaches enough points.
    ValidationResiduals residuals(sparse, kept);
    std::size_t swaps = 0;
    for (std::size_t i = 0; i < kept.size(); ++i) {
        if (kept.sameGaussian(i, start, i)) continue;
        ++swaps;
        double change = 0;
        std::size_t points = 0;
        residuals.changes({{&kept, i}}, {{{&start, i}}}, &change, &points);
        EXPECT_GE(points, kMinChoicePoints) << "Gaussian " << i;
    }
    EXPECT_EQ(swaps, r.swapped);
}

// The validated split changes only what lowers the validation score: its report's score is the
// split model's, every split adds two Gaussians, the budget holds, and flags, cells and offsets
// follow the children.
TEST(ValidatedSplit, SplitsOnlyWhatTheValidationPointsMeasureToPay)
{
    const ChoiceFixture fx;
    const StageOneResult s1 = fx.rest->stageOne->apply(fx.deformation.transforms, fx.deformation.nodeMoving);
    for (std::size_t budget : {std::size_t(6), std::size_t(4000)}) {
        GaussianCloud model = s1.deformed;
        std::vector<std::uint8_t> moving = s1.moving;
        std::vector<std::int32_t> cells = fx.rest->grid ? fx.rest->grid->gaussianCell()
                                                        : std::vector<std::int32_t>(model.size(), 0);
        std::vector<float> curve(3 * model.size(), 0.0f);
        const ValidatedSplitReport r = validatedSplit(*fx.validation, fx.rest->model, fx.deformation, {}, s1.deformed,
                                                      budget, {model, moving, cells, &curve});
        EXPECT_GT(r.split, 0u);
        EXPECT_EQ(r.added, 2 * r.split);
        EXPECT_LE(r.added, budget);
        EXPECT_EQ(model.size(), s1.deformed.size() + r.added);
        EXPECT_EQ(moving.size(), model.size());
        EXPECT_EQ(cells.size(), model.size());
        EXPECT_EQ(curve.size(), 3 * model.size());
        EXPECT_NEAR(r.before, fx.validation->score(s1.deformed), 1e-6 * r.before);
        EXPECT_NEAR(r.after, fx.validation->score(model), 1e-6 * r.before);
        EXPECT_LT(r.after, r.before);
    }
}

// The per-Gaussian step (one visit of the points for all candidates) keeps the same Gaussians, to
// the bit, as the rule written plainly: heaviest first, each candidate scored by change() on at
// least kMinChoicePoints points, the best applied at once.
TEST(GaussianChoice, OneVisitForAllCandidatesMatchesTheRuleWrittenPlainly)
{
    const ChoiceFixture fx;
    // Three candidates that differ from the kept model in overlapping Gaussians.
    GaussianCloud moved = fx.stage1, bright = fx.stage1;
    for (std::size_t i = 0; i < moved.size(); i += 3) {
        const Vec3f m = moved.mean(i);
        moved.setMean(i, Vec3f{m.x + 0.5f * moved.scale(i).x, m.y, m.z});
    }
    for (std::size_t i = 0; i < bright.size(); i += 2) bright.opacities[i] += 0.7f;
    const GaussianCloud blank = blankedParity(fx.stage1, 1);
    const std::vector<StageTwoCandidate> candidates{{"moved", &moved}, {"bright", &bright}, {"blank", &blank}};
    const GaussianCloud start = blankedParity(fx.stage1, 0);

    GaussianCloud plain = start;
    ValidationResiduals r(*fx.validation, plain);
    std::vector<std::pair<double, std::size_t>> order;
    for (std::size_t i = 0; i < plain.size(); ++i) {
        bool differs = false;
        for (const StageTwoCandidate& c : candidates) differs = differs || !plain.sameGaussian(i, *c.model, i);
        const Vec3f s = plain.scale(i);
        if (differs) order.push_back({-double(plain.alpha(i)) * double(s.x) * double(s.y) * double(s.z), i});
    }
    std::stable_sort(order.begin(), order.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    std::size_t swapped = 0;
    for (const auto& [mass, i] : order) {
        const GaussianCloud* best = nullptr;
        double bestChange = 0.0;
        for (const StageTwoCandidate& c : candidates) {
            if (plain.sameGaussian(i, *c.model, i)) continue;
            double d = 0;
            std::size_t points = 0;
            r.changes({{&plain, i}}, {{{c.model, i}}}, &d, &points);
            EXPECT_EQ(d, r.change({{&plain, i}}, {{c.model, i}}));
            if (d < bestChange && points >= kMinChoicePoints) bestChange = d, best = c.model;
        }
        if (!best) continue;
        r.apply({{&plain, i}}, {{best, i}});
        plain.assign(i, *best, i);
        ++swapped;
    }
    ASSERT_GT(swapped, plain.size() / 10);
    GaussianChoiceReport report;
    const GaussianCloud kept = chooseEachGaussian(*fx.validation, candidates, start, report);
    EXPECT_EQ(report.swapped, swapped);
    EXPECT_EQ(report.tried, order.size());
    EXPECT_EQ(report.after, r.score());
    EXPECT_EQ(kept.means, plain.means);
    EXPECT_EQ(kept.opacities, plain.opacities);
}
