#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "field/FeatureField.h"
#include "core/Error.h"
#include "core/Polar.h"
#include "stage2/Densify.h"
#include "support/TestGaussians.h"

using namespace splatwarp;
using splatwarp::test::threeGaussians;

namespace {

/// Moments of the field on a lattice (midpoint rule): mass of O, its mean and covariance, and
/// the integral of each F channel.
struct FieldMoments {
    double mass = 0;
    double mean[3] = {0, 0, 0};
    double cov[3][3] = {};
    std::vector<double> f;
};

/// Spacing h = 0.04: the midpoint rule on a Gaussian errs by ~2 exp(-2 pi^2 sigma^2 / h^2) < 1e-30
/// for every sigma >= 0.08 (the smallest, before and after the split). The box [-1.6, 1.6]^3 holds
/// every Gaussian and child out to > 4.5 sigma along its longest axis (mass beyond < 1e-5 of it,
/// and nearly the same before and after).
FieldMoments moments(const GaussianCloud& g, float cutoff)
{
    const std::vector<float> points = splatwarp::test::latticePoints(0.04, -1.6, 81);
    const std::size_t m = points.size() / 3;
    FeatureOptions fo;
    fo.cutoff = cutoff;
    std::vector<float> o(m), f(m * std::size_t(g.shStride()));
    evaluateFeatures(g, points.data(), m, fo, f.data(), o.data());
    FieldMoments r;
    r.f.assign(std::size_t(g.shStride()), 0.0);
    for (std::size_t j = 0; j < m; ++j) {
        r.mass += o[j];
        for (int a = 0; a < 3; ++a) r.mean[a] += o[j] * points[3 * j + std::size_t(a)];
        for (int c = 0; c < g.shStride(); ++c) r.f[std::size_t(c)] += f[j * std::size_t(g.shStride()) + std::size_t(c)];
    }
    for (int a = 0; a < 3; ++a) r.mean[a] /= r.mass;
    for (std::size_t j = 0; j < m; ++j)
        for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b)
                r.cov[a][b] += o[j] * (points[3 * j + std::size_t(a)] - r.mean[a]) * (points[3 * j + std::size_t(b)] - r.mean[b]);
    for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) r.cov[a][b] /= r.mass;
    return r;
}

/// Share of a 3D Gaussian's mass beyond Mahalanobis radius r: P(chi^2_3 > r^2).
double chi3Tail(double r) { return std::erfc(r / std::sqrt(2.0)) + std::sqrt(2.0 / M_PI) * r * std::exp(-0.5 * r * r); }

/// Split all three with an offset and compare the field's moments; `tolerance` relative to the parent's.
void expectSplitKeepsMoments(float cutoff, double tolerance, float offset)
{
    GaussianCloud g = threeGaussians();
    const FieldMoments before = moments(g, cutoff);
    std::vector<std::uint8_t> moving(3, 1);
    std::vector<std::int32_t> cell = {4, 5, -1};
    FitState d{g, moving, cell};
    ASSERT_EQ(splitGaussians(d, {0, 1, 2}, keepMomentsSplit(offset)), 3u);
    ASSERT_EQ(g.size(), 6u);
    const FieldMoments after = moments(g, cutoff);
    EXPECT_NEAR(after.mass / before.mass, 1.0, tolerance);
    const double extent = std::sqrt(before.cov[0][0] + before.cov[1][1] + before.cov[2][2]);
    for (int a = 0; a < 3; ++a) {
        EXPECT_NEAR(after.mean[a], before.mean[a], tolerance * extent) << "axis " << a;
        for (int b = 0; b < 3; ++b)
            EXPECT_NEAR(after.cov[a][b], before.cov[a][b], tolerance * extent * extent) << a << "," << b;
    }
    for (std::size_t c = 0; c < before.f.size(); ++c)
        EXPECT_NEAR(after.f[c], before.f[c], tolerance * std::fabs(before.f[c]) + 1e-9 * before.mass) << "F " << c;
}

} // namespace

// Cutoff 1e-9: the mass any Gaussian leaves uncounted is P(chi^2_3 > 2 ln(alpha' / 1e-9)) < 2e-7
// (alpha' = 0.06 / 1.2 the smallest), float rounding of 0.5M values summed in double ~1e-7: 1e-5
// (measured 6e-8 for the mass). At the default offset and at 0.8 (children 0.6 sigma wide).
TEST(Densify, SplitKeepsMassMeanCovarianceAndColour)
{
    expectSplitKeepsMoments(1e-9f, 1e-5, kSplitOffset);
    expectSplitKeepsMoments(1e-9f, 1e-5, 0.8f);
}

// At the default cutoff 1/255 a pair below alpha G = 1/255 is not counted: a Gaussian of opacity a
// (split with offset 0.8: children of opacity a / 1.2) loses the share P(chi^2_3 > 2 ln(255 a)) of its mass m = a (2 pi)^1.5 sx sy sz, a child (a / 1.2)
// a little more. The relative change is then below sum m tail(a / 1.2) / sum m (1 - tail(a)),
// 0.021 for these three (measured 0.0033): the stated tolerance.
TEST(Densify, SplitKeepsMassWithinTheCutoffsTail)
{
    const GaussianCloud g = threeGaussians();
    auto tail = [](double a) { return chi3Tail(std::sqrt(2.0 * std::log(255.0 * a))); };
    double lost = 0, kept = 0;
    for (std::size_t i = 0; i < g.size(); ++i) {
        const Vec3f s = g.scale(i);
        const double m = g.alpha(i) * double(s.x) * s.y * s.z;
        lost += m * tail(g.alpha(i) / 1.2);
        kept += m * (1.0 - tail(g.alpha(i)));
    }
    EXPECT_LT(lost / kept, 0.05);
    expectSplitKeepsMoments(1.0f / 255.0f, lost / kept, 0.8f);
}

TEST(Densify, ChildrenInheritCellAndMovingFlagAndSplitAlongTheLongestAxis)
{
    GaussianCloud g = threeGaussians();
    const GaussianCloud parent = g;
    std::vector<std::uint8_t> moving = {1, 0, 1};
    std::vector<std::int32_t> cell = {7, 3, 9};
    FitState d{g, moving, cell};
    splitGaussian(d, 2, keepMomentsSplit(0.8f)); // axis-aligned, longest along z (0.18): children 0.6 x as wide, alpha / 1.2
    ASSERT_EQ(g.size(), 4u);
    EXPECT_EQ(moving, (std::vector<std::uint8_t>{1, 0, 1, 1}));
    EXPECT_EQ(cell, (std::vector<std::int32_t>{7, 3, 9, 9}));
    const float dz = 0.8f * 0.18f;
    EXPECT_NEAR(g.mean(2).z - parent.mean(2).z, dz, 1e-6f);
    EXPECT_NEAR(g.mean(3).z - parent.mean(2).z, -dz, 1e-6f);
    EXPECT_NEAR(g.mean(2).x, parent.mean(2).x, 1e-7f);
    EXPECT_NEAR(g.scale(3).z, 0.18f * 0.6f, 1e-6f);
    EXPECT_NEAR(g.scale(3).x, 0.09f, 1e-6f);
    EXPECT_NEAR(g.alpha(3), 0.06f / 1.2f, 1e-6f);
    for (int c = 0; c < g.shStride(); ++c) EXPECT_EQ(g.shOf(3)[c], parent.shOf(2)[c]);
    // The other Gaussians are untouched.
    EXPECT_EQ(std::memcmp(g.means.data(), parent.means.data(), 6 * sizeof(float)), 0);
}

TEST(Densify, PruneRemovesExactlyTheMovingGaussiansBelowTheThreshold)
{
    GaussianCloud g;
    g.resize(6, 1);
    const float alphas[6] = {0.5f, 0.003f, 0.001f, 0.0039f, 0.004f, 0.2f};
    const std::vector<std::uint8_t> movingIn = {1, 1, 0, 1, 1, 1};
    for (std::size_t i = 0; i < 6; ++i) {
        g.opacities[i] = std::log(alphas[i] / (1.0f - alphas[i]));
        g.setMean(i, Vec3f{float(i), 0.5f * float(i), -float(i)});
        for (int c = 0; c < g.shStride(); ++c) g.shOf(i)[c] = float(i) + 0.01f * float(c);
        g.logScales[3 * i] = -float(i);
    }
    const GaussianCloud in = g;
    std::vector<std::uint8_t> moving = movingIn;
    std::vector<std::int32_t> cell = {0, 1, 2, 3, 4, 5};
    FitState d{g, moving, cell};
    // Removed: 1 (0.003) and 3 (0.0039); 2 is below but static, 4 is at 0.004 >= 1/255.
    EXPECT_EQ(pruneMovingBelow(d, 1.0f / 255.0f), 2u);
    const std::vector<std::size_t> kept = {0, 2, 4, 5};
    ASSERT_EQ(g.size(), kept.size());
    EXPECT_EQ(cell, (std::vector<std::int32_t>{0, 2, 4, 5}));
    EXPECT_EQ(moving, (std::vector<std::uint8_t>{1, 0, 1, 1}));
    GaussianCloud expected;
    expected.shDegree = 1;
    for (std::size_t i : kept) expected.append(in, i);
    auto same = [](const std::vector<float>& a, const std::vector<float>& b) {
        return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0;
    };
    EXPECT_TRUE(same(g.means, expected.means));
    EXPECT_TRUE(same(g.rotations, expected.rotations));
    EXPECT_TRUE(same(g.logScales, expected.logScales));
    EXPECT_TRUE(same(g.opacities, expected.opacities));
    EXPECT_TRUE(same(g.sh, expected.sh));
    EXPECT_EQ(pruneMovingBelow(d, 0.0f), 0u);
}

TEST(Densify, StretchedGaussiansAreTheMovingOnesOfCellsAboveTheThreshold)
{
    // Cell 0: identity. Cell 1: a rotation (singular values 1). Cell 2: stretched 1.4 along a
    // rotated axis. Cell 3: squashed to 0.5 (largest singular value 1).
    const float c = std::cos(0.7f), s = std::sin(0.7f);
    std::vector<float> gradient = {1, 0, 0, 0, 1, 0, 0, 0, 1,
                                   c, -s, 0, s, c, 0, 0, 0, 1,
                                   1.4f * c, -s, 0, 1.4f * s, c, 0, 0, 0, 1,
                                   0.5f, 0, 0, 0, 1, 0, 0, 0, 1};
    EXPECT_NEAR(largestSingularValue(&gradient[18]), 1.4f, 1e-5f);
    EXPECT_NEAR(largestSingularValue(&gradient[9]), 1.0f, 1e-5f);
    const std::vector<std::uint8_t> moving = {1, 1, 1, 0, 1, 1, 1};
    const std::vector<std::int32_t> cell = {0, 1, 2, 2, 3, -1, 2};
    EXPECT_EQ(stretchedGaussians(moving, cell, gradient, 1.3f), (std::vector<std::size_t>{2, 6}));
    EXPECT_TRUE(stretchedGaussians(moving, cell, gradient, 1.5f).empty());
}

TEST(Densify, FromVdbsShrinkKeepsTheOpacityBitForBitAndBadOffsetsAreRefused)
{
    const GaussianCloud parent = threeGaussians();
    std::vector<std::uint8_t> moving(3, 1);
    std::vector<std::int32_t> cell(3, 0);
    GaussianCloud g = parent;
    FitState d{g, moving, cell};
    ASSERT_EQ(splitGaussians(d, {0, 2}, shrinkSplit(0.5f)), 2u);
    ASSERT_EQ(g.size(), 5u);
    // Both children of each: the parent's logit as it is (a round trip through alpha could move it),
    // 0.6 x as wide along the longest axis.
    for (const auto& [child, of] : std::vector<std::pair<std::size_t, std::size_t>>{{0, 0}, {3, 0}, {2, 2}, {4, 2}}) {
        EXPECT_EQ(g.opacities[child], parent.opacities[of]);
        const int axis = longestAxis(parent, of);
        EXPECT_NEAR(g.scale(child)[axis], 0.6f * parent.scale(of)[axis], 1e-6f);
    }
    for (const float bad : {0.0f, -0.1f, 0.9f, std::nanf("")}) {
        EXPECT_THROW(keepMomentsSplit(bad), InputError) << bad;
        EXPECT_THROW(shrinkSplit(bad), InputError) << bad;
    }
}

TEST(Densify, AFitStateKeepsItsCurveRowsInStepThroughReplaceAndPrune)
{
    const GaussianCloud parent = threeGaussians();
    GaussianCloud g = parent;
    std::vector<std::uint8_t> moving = {1, 0, 1};
    std::vector<std::int32_t> cell = {4, 5, 6};
    std::vector<float> curve = {0, 0, 1, 0, 0, 2, 0, 0, 3};
    FitState d{g, moving, cell, &curve};
    // Gaussian 2 becomes rows 1 and 0 of `from` (parent's 1 and 0): flags and curve rows from
    // fromMoving / fromCurve, its cell for both.
    const std::uint8_t fromMoving[3] = {1, 0, 1};
    const float fromCurve[9] = {7, 7, 7, 8, 8, 8, 9, 9, 9};
    d.replace(2, parent, {1, 0}, fromMoving, fromCurve);
    ASSERT_EQ(g.size(), 4u);
    EXPECT_TRUE(g.sameGaussian(2, parent, 1));
    EXPECT_TRUE(g.sameGaussian(3, parent, 0));
    EXPECT_EQ(moving, (std::vector<std::uint8_t>{1, 0, 0, 1}));
    EXPECT_EQ(cell, (std::vector<std::int32_t>{4, 5, 6, 6}));
    EXPECT_EQ(curve, (std::vector<float>{0, 0, 1, 0, 0, 2, 8, 8, 8, 7, 7, 7}));
    // Without sources, the new row repeats the replaced Gaussian's flag and curve.
    d.replace(0, parent, {2, 2});
    EXPECT_EQ(moving.back(), 1);
    EXPECT_EQ(std::vector<float>(curve.end() - 3, curve.end()), (std::vector<float>{0, 0, 1}));
    // The prune drops the curve rows of what it removes.
    g.opacities[3] = -20.0f; // moving, alpha ~2e-9
    ASSERT_EQ(pruneMovingBelow(d, 0.01f), 1u);
    EXPECT_EQ(curve.size(), 3 * g.size());
    EXPECT_EQ(std::vector<float>(curve.begin() + 9, curve.begin() + 12), (std::vector<float>{0, 0, 1}));
}
