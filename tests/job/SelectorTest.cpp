// The deform pipeline's one selector (job/Selector.h): its points are never the judge's, and its
// three modes keep what the score prefers (best: the model that is not blanked; region mix: each
// half from the candidate that holds it; per Gaussian: never a higher score than the mix).
#include <gtest/gtest.h>

#include <set>
#include <tuple>

#include "ChoiceFixture.h"
#include "job/Selector.h"

using namespace splatwarp;
using namespace splatwarp::test;

namespace {

/// The fixture's stripes bend with the pipeline's validation points (the judge's seed XOR
/// kValidationSeedXor) and the judge's own.
struct SelectorFixture : ChoiceFixture {
    HeldOutOptions judgeOptions;
    JudgeRest judgeRest, validationRest;
    std::unique_ptr<Selector> selector;

    SelectorFixture()
    {
        judgeOptions.points = 20000;
        judgeRest = prepareJudgeRest(rest->model, judgeOptions);
        HeldOutOptions v = judgeOptions;
        v.seed ^= kValidationSeedXor;
        validationRest = prepareValidationRest(rest->model, v);
        selector = std::make_unique<Selector>(rest->model, validationRest, deformation);
    }
};

} // namespace

TEST(Selector, ItsPointsAreNeverTheJudgesAndItsModesKeepWhatTheScorePrefers)
{
    const SelectorFixture fx;
    const Judge judge(fx.rest->model, fx.judgeRest, fx.deformation);
    std::set<std::tuple<float, float, float>> judged;
    const std::vector<float>& j = judge.points().rest;
    for (std::size_t p = 0; p + 2 < j.size(); p += 3) judged.insert({j[p], j[p + 1], j[p + 2]});
    const std::vector<float>& v = fx.selector->points().points().rest;
    ASSERT_GT(v.size(), 3000u);
    std::size_t shared = 0;
    for (std::size_t p = 0; p + 2 < v.size(); p += 3) shared += judged.count({v[p], v[p + 1], v[p + 2]});
    EXPECT_EQ(shared, 0u);

    const GaussianCloud left = fx.blanked(true), right = fx.blanked(false);
    const Selection best = fx.selector->best({&left, &fx.stage1, &right});
    EXPECT_EQ(best.best, 1u);
    EXPECT_EQ(best.scores[1], fx.selector->score(fx.stage1));

    StageTwoChoice choice;
    const std::vector<StageTwoCandidate> halves{{"left", &left}, {"right", &right}};
    const GaussianCloud mix = fx.selector->regionMix(halves, true, choice);
    EXPECT_EQ(choice.kept, "mix");
    EXPECT_LT(fx.selector->score(mix), 0.5 * std::min(best.scores[0], best.scores[2]));

    GaussianChoiceReport each;
    const GaussianCloud kept = fx.selector->perGaussian(halves, mix, each);
    EXPECT_LE(fx.selector->score(kept), fx.selector->score(mix) * (1 + 1e-9));
    EXPECT_NEAR(each.before, fx.selector->score(mix), 1e-9 * each.before); // summed in another order
}
