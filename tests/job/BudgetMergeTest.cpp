// The budget met after the fit: families of split children merged back, least loss first (issue 33).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <numeric>
#include <vector>

#include "ChoiceFixture.h"
#include "core/GaussianSplit.h"
#include "core/Polar.h"
#include "deform/CurveSplit.h"
#include "field/GaussianMath.h"
#include "job/BudgetMerge.h"
#include "stage2/Densify.h"

using namespace splatwarp;
using namespace splatwarp::test;

namespace {

/// Gaussian i's covariance R diag(s^2) R^T.
Mat3d covarianceOf(const GaussianCloud& g, std::size_t i)
{
    const Quatf q = g.rotation(i);
    const Vec3f s = g.scale(i);
    return gaussianCovariance(Quatd{q.w, q.x, q.y, q.z}, Vec3d(s.x, s.y, s.z));
}

/// A model of `g` with Gaussian i replaced by the rows of `children` (the first in i's slot), and
/// its parents: i's for each child, the identity elsewhere.
GaussianCloud replaced(const GaussianCloud& g, std::size_t i, const GaussianCloud& children, std::vector<std::int32_t>& parent)
{
    GaussianCloud out = g;
    out.assign(i, children, 0);
    for (std::size_t k = 1; k < children.size(); ++k) {
        out.append(children, k);
        parent.push_back(std::int32_t(i));
    }
    return out;
}

} // namespace

// Stage II's split keeps the parent's mass, mean and covariance, so merging its pair gives the
// parent back (a wrong moment, a mass weight or a covariance term left out, would not).
TEST(BudgetMerge, AMergedPairIsTheGaussianItWasSplitFrom)
{
    const ChoiceFixture fx;
    for (std::size_t i : {std::size_t(5), std::size_t(123), std::size_t(777)}) {
        GaussianCloud g = fx.stage1;
        g.setRotation(i, Quatf{0.9f, 0.2f, -0.3f, 0.1f}); // a turned one: the covariance's off-diagonal terms count
        g.opacities[i] = 0.3f;
        for (int axis = 0; axis < 3; ++axis) {
            GaussianCloud children;
            children.shDegree = g.shDegree;
            appendSplitChildren(g, i, axis, keepMomentsSplit(), children);
            ASSERT_EQ(children.size(), 2u);
            GaussianCloud merged;
            merged.shDegree = g.shDegree;
            appendMerged(children, {0, 1}, merged);
            ASSERT_EQ(merged.size(), 1u);
            for (int a = 0; a < 3; ++a) EXPECT_NEAR(merged.mean(0)[a], g.mean(i)[a], 1e-5);
            const Mat3d want = covarianceOf(g, i), got = covarianceOf(merged, 0);
            for (int a = 0; a < 3; ++a)
                for (int b = 0; b < 3; ++b) EXPECT_NEAR(got.m[a][b], want.m[a][b], 1e-4 * want.m[a][a]) << a << b;
            EXPECT_NEAR(merged.alpha(0), g.alpha(i), 1e-5);
            for (int k = 0; k < g.shStride(); ++k) EXPECT_NEAR(merged.shOf(0)[k], g.shOf(i)[k], 1e-6);
        }
    }
}

// Two families of two: one a moment-keeping split (merging it costs nothing), one whose second
// child sits far from the first (merging it smears both). A budget one below the count merges the
// cheap one only; the score change the report states is the judge's; the budget is met exactly.
TEST(BudgetMerge, MergesTheFamiliesThatBuyLeastUntilTheBudgetHolds)
{
    const ChoiceFixture fx;
    const std::size_t cheap = 300, costly = 900;
    std::vector<std::int32_t> parent(fx.stage1.size());
    std::iota(parent.begin(), parent.end(), std::int32_t(0));
    GaussianCloud pair;
    pair.shDegree = fx.stage1.shDegree;
    appendSplitChildren(fx.stage1, cheap, 0, keepMomentsSplit(), pair);
    GaussianCloud model = replaced(fx.stage1, cheap, pair, parent);
    GaussianCloud apart;
    apart.shDegree = fx.stage1.shDegree;
    apart.append(fx.stage1, costly);
    apart.append(fx.stage1, costly + 1); // a neighbour's copy: the two sit apart
    model = replaced(model, costly, apart, parent);
    const std::size_t n = model.size();
    ASSERT_EQ(n, fx.stage1.size() + 2);

    BudgetMergeReport r;
    const GaussianCloud one = mergeToBudget(*fx.validation, model, parent, n - 1, r);
    EXPECT_EQ(one.size(), n - 1);
    EXPECT_EQ(r.families, 2u);
    EXPECT_EQ(r.merged, 1u);
    EXPECT_EQ(r.removed, 1u);
    EXPECT_NEAR(one.mean(cheap).x, fx.stage1.mean(cheap).x, 1e-5); // the cheap family is its parent again
    EXPECT_TRUE(one.sameGaussian(costly, model, costly));           // the costly one is untouched
    EXPECT_NEAR(r.after - r.before, fx.validation->score(one) - fx.validation->score(model), 1e-6);

    BudgetMergeReport all; // a budget of the rest model's count merges both
    EXPECT_EQ(mergeToBudget(*fx.validation, model, parent, fx.stage1.size(), all).size(), fx.stage1.size());
    EXPECT_EQ(all.merged, 2u);
    EXPECT_GT(all.after, r.after); // the costly merge costs

    BudgetMergeReport none; // a budget the model fits: nothing merged
    EXPECT_EQ(mergeToBudget(*fx.validation, model, parent, n, none).size(), n);
    EXPECT_EQ(none.merged, 0u);
    BudgetMergeReport below;
    EXPECT_THROW(mergeToBudget(*fx.validation, model, parent, fx.stage1.size() - 1, below), UsageError);
}

// Three Gaussians far apart along the bar, each split in three, counted as one family of nine:
// merged whole they become one smear, merged in runs of three along their spread each is itself
// again. A budget of six fewer takes the runs (merging whole would remove eight).
TEST(BudgetMerge, AFamilyOfNineMergesIntoRunsOfThreeFirst)
{
    const ChoiceFixture fx;
    std::vector<std::size_t> byX(fx.stage1.size());
    std::iota(byX.begin(), byX.end(), std::size_t(0));
    std::sort(byX.begin(), byX.end(), [&](std::size_t a, std::size_t b) { return fx.stage1.mean(a).x < fx.stage1.mean(b).x; });
    const std::size_t n0 = fx.stage1.size();
    const std::size_t abc[3] = {byX[n0 / 2], byX[n0 / 4], byX[3 * n0 / 4]};
    std::vector<std::int32_t> parent(n0);
    std::iota(parent.begin(), parent.end(), std::int32_t(0));
    GaussianCloud model = fx.stage1;
    for (std::size_t g : abc) {
        GaussianCloud kids;
        kids.shDegree = model.shDegree;
        appendSplitChildren(fx.stage1, g, longestAxis(fx.stage1, g), curveSplitPattern(0.0, 0.0), kids);
        model = replaced(model, g, kids, parent);
        parent[g] = std::int32_t(abc[0]);
        for (std::size_t k = parent.size() - 2; k < parent.size(); ++k) parent[k] = std::int32_t(abc[0]);
    }
    const std::size_t n = model.size();
    ASSERT_EQ(n, n0 + 6);

    BudgetMergeReport r;
    const GaussianCloud out = mergeToBudget(*fx.validation, model, parent, n - 6, r);
    EXPECT_EQ(out.size(), n - 6);
    EXPECT_EQ(r.families, 1u);
    EXPECT_EQ(r.mergedToRuns, 1u);
    EXPECT_EQ(r.merged, 0u);
    for (std::size_t g : abc) // each run is one Gaussian's children, merged in its slot: that Gaussian's mean
        for (int a = 0; a < 3; ++a) EXPECT_NEAR(out.mean(g)[a], fx.stage1.mean(g)[a], 1e-4) << g;
    BudgetMergeReport whole; // eight fewer: the whole family, one Gaussian
    EXPECT_EQ(mergeToBudget(*fx.validation, model, parent, n - 8, whole).size(), n - 8);
    EXPECT_EQ(whole.merged, 1u);
    EXPECT_GT(whole.after, r.after);
}
