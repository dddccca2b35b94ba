#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "core/Outliers.h"
#include "field/FieldTestModels.h"

using namespace splatwarp;
using namespace splatwarp::test;

namespace {

/// A bulk in [-1, 1]^3 and `far` centres moved along random directions to `distance` from the origin.
GaussianCloud bulkWithFar(std::size_t n, std::size_t far, double distance, std::vector<std::uint8_t>& planted)
{
    GaussianCloud g = randomCloud(n, 0, 11);
    planted.assign(n, 0);
    std::mt19937 rng(5);
    std::normal_distribution<double> nd(0.0, 1.0);
    for (std::size_t k = 0; k < far; ++k) {
        const std::size_t i = (k * 7919 + 13) % n;
        Vec3d d(nd(rng), nd(rng), nd(rng));
        d = d * (distance / length(d));
        g.setMean(i, Vec3f(float(d.x), float(d.y), float(d.z)));
        planted[i] = 1;
    }
    return g;
}

/// The naive quantile: sort, take the nearest rank.
double naiveQuantile(const GaussianCloud& g, int axis, double q)
{
    std::vector<double> v;
    for (std::size_t i = 0; i < g.size(); ++i) v.push_back(g.means[3 * i + std::size_t(axis)]);
    std::sort(v.begin(), v.end());
    return v[std::size_t(std::floor(q * double(v.size() - 1) + 0.5))];
}

} // namespace

TEST(Outliers, FindsExactlyThePlantedFloaters)
{
    std::vector<std::uint8_t> planted;
    const GaussianCloud g = bulkWithFar(5000, 20, 60.0, planted);
    const Outliers f = findOutliers(g);
    EXPECT_EQ(f.farCount, 20u);
    EXPECT_EQ(f.giantCount, 0u);
    EXPECT_EQ(f.either(), planted);
    EXPECT_EQ(f.far, planted);
    for (int a = 0; a < 3; ++a) {
        EXPECT_EQ(f.bulkLo[a], naiveQuantile(g, a, kBulkQuantile));
        EXPECT_EQ(f.bulkHi[a], naiveQuantile(g, a, 1.0 - kBulkQuantile));
    }
    EXPECT_NEAR(f.bulkSize, 1.96, 0.1); // the central 98% of a uniform [-1, 1]
    EXPECT_GT(f.boxRatio, 30.0);        // floaters on both sides of a 60-unit sphere
}

TEST(Outliers, ACleanModelOrAPointHasNone)
{
    std::vector<std::uint8_t> planted;
    EXPECT_EQ(findOutliers(bulkWithFar(5000, 0, 0.0, planted)).farCount, 0u);
    // Near ones are not far: within the bulk's size of its box.
    const Outliers near = findOutliers(bulkWithFar(5000, 20, 2.5, planted));
    EXPECT_EQ(near.farCount, 0u);
    EXPECT_EQ(near.giantCount, 0u); // randomCloud: sigma at most 0.25 of a bulk about 2
    EXPECT_LT(near.boxRatio, 3.0);
    // One point repeated: no bulk size, nothing is far.
    GaussianCloud same = randomCloud(100, 0, 3);
    for (std::size_t i = 0; i < same.size(); ++i) same.setMean(i, Vec3f(0.5f, 0.5f, 0.5f));
    const Outliers point = findOutliers(same);
    EXPECT_EQ(point.farCount + point.giantCount, 0u);
    EXPECT_EQ(findOutliers(GaussianCloud{}).farCount, 0u);
}

TEST(Outliers, NonFiniteValuesAreNeitherCountedNorOutliers)
{
    std::vector<std::uint8_t> planted;
    GaussianCloud g = bulkWithFar(2000, 5, 100.0, planted);
    g.means[3 * 1 + 2] = std::numeric_limits<float>::quiet_NaN();
    g.means[3 * 2] = std::numeric_limits<float>::infinity();
    g.logScales[3 * 3] = std::numeric_limits<float>::quiet_NaN();
    g.logScales[3 * 4 + 1] = 1000.0f; // exp() overflows
    const Outliers f = findOutliers(g);
    EXPECT_EQ(f.farCount, 5u);
    EXPECT_EQ(f.giantCount, 0u);
    EXPECT_EQ(f.far[1], 0);
    EXPECT_EQ(f.far[2], 0);
    EXPECT_TRUE(std::isfinite(f.largestSigma));
    EXPECT_TRUE(std::isfinite(f.boxRatio));
}

TEST(Outliers, GiantsAreThoseWiderThanHalfTheBulk)
{
    std::vector<std::uint8_t> planted;
    GaussianCloud g = bulkWithFar(4000, 0, 0.0, planted);
    const double bulk = findOutliers(g).bulkSize;
    // One axis of each just over or just under kGiantSigma x the bulk; centres unchanged.
    g.logScales[3 * 10 + 2] = float(std::log(0.55 * bulk));
    g.logScales[3 * 20] = float(std::log(20.0 * bulk));
    g.logScales[3 * 30 + 1] = float(std::log(0.45 * bulk));
    const Outliers f = findOutliers(g);
    EXPECT_EQ(f.bulkSize, bulk);
    EXPECT_EQ(f.giantCount, 2u);
    EXPECT_EQ(f.giant[10], 1);
    EXPECT_EQ(f.giant[20], 1);
    EXPECT_EQ(f.giant[30], 0);
    EXPECT_EQ(f.farCount, 0u);
    EXPECT_NEAR(f.largestSigma, 20.0 * bulk, 1e-5 * bulk);
    const std::vector<std::uint8_t> e = f.either();
    EXPECT_EQ(std::count(e.begin(), e.end(), 1), 2);
}
