// The block evaluation of the rest targets against the per-point one (evaluateFeatures): the
// same contributing pairs, summed in the same order, so the same bits.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>

#include "field/FieldTestModels.h"
#include "stage2/BlockFeatures.h"
#include "stage2/StageTwoTestProblem.h"

using namespace splatwarp;
using namespace splatwarp::test;

TEST(BlockFeatures, SameBitsAsThePerPointEvaluation)
{
    for (int degree : {0, 2, 3})
        for (int n : {2, 3, 4}) {
            GaussianCloud cloud = randomCloud(80, degree, 31u + std::uint32_t(degree), 0.45f, 0.01f, 0.12f);
            for (std::size_t i = 0; i < cloud.size(); i += 4) cloud.logScales[3 * i + 2] = -14.0f; // flat Gaussians
            StageTwoOptions so;
            const SampleSet s = latticeSampleSet(cloud, 9, 0.8f, n, so);
            const std::size_t m = s.sampleCount();
            FeatureOptions fo;
            fo.filterVariance = 0.2f * s.spacing * s.spacing;
            const int stride = cloud.shStride();
            std::vector<float> fa(m * std::size_t(stride)), oa(m), fb(fa.size()), ob(m);
            FeatureStats sa, sb;
            evaluateFeatures(cloud, s.restPositions.data(), m, fo, fa.data(), oa.data(), &sa);
            sb = evaluateBlockFeatures(cloud, s.restPositions.data(), s.sampleCell.data(), m, fo, fb.data(), ob.data());
            EXPECT_EQ(sa.pairsContributing, sb.pairsContributing) << "degree " << degree << " n " << n;
            EXPECT_GT(sb.pairsContributing, 0u);
            EXPECT_EQ(std::memcmp(fa.data(), fb.data(), fa.size() * sizeof(float)), 0) << "degree " << degree << " n " << n;
            EXPECT_EQ(std::memcmp(oa.data(), ob.data(), oa.size() * sizeof(float)), 0) << "degree " << degree << " n " << n;
        }
}

// Points in no cell order (held-out and validation points): Morton-ordered into blocks and put
// back, the same bits as the per-point evaluation; also for a cluster with far outliers (long
// blocks), one point, and a point that is not finite.
TEST(BlockFeatures, AnyPointsInMortonBlocksGiveTheSameBitsAsThePerPointEvaluation)
{
    for (int degree : {0, 3}) {
        GaussianCloud cloud = randomCloud(120, degree, 5u + std::uint32_t(degree), 0.45f, 0.01f, 0.12f);
        std::mt19937 rng(11);
        std::uniform_real_distribution<float> u(-0.6f, 0.6f);
        std::vector<float> points;
        for (int j = 0; j < 3000; ++j)
            for (int a = 0; a < 3; ++a) points.push_back(u(rng));
        for (float far : {40.0f, -75.0f}) points.insert(points.end(), {far, 0.1f, far});
        FeatureOptions fo;
        fo.filterVariance = 1e-3f;
        const int stride = cloud.shStride();
        for (std::size_t m : {points.size() / 3, std::size_t(1)}) {
            std::vector<float> fa(m * std::size_t(stride)), oa(m), fb(fa.size(), -1.0f), ob(m, -1.0f);
            evaluateFeatures(cloud, points.data(), m, fo, fa.data(), oa.data());
            evaluatePointFeatures(cloud, points.data(), m, fo, fb.data(), ob.data());
            EXPECT_EQ(std::memcmp(fa.data(), fb.data(), fa.size() * sizeof(float)), 0) << "degree " << degree << " m " << m;
            EXPECT_EQ(std::memcmp(oa.data(), ob.data(), oa.size() * sizeof(float)), 0) << "degree " << degree << " m " << m;
        }
        points[4] = std::nanf("");
        std::vector<float> oa(points.size() / 3), ob(oa.size());
        evaluateFeatures(cloud, points.data(), oa.size(), fo, nullptr, oa.data());
        evaluatePointFeatures(cloud, points.data(), ob.size(), fo, nullptr, ob.data());
        EXPECT_EQ(std::memcmp(oa.data(), ob.data(), oa.size() * sizeof(float)), 0);
    }
}

// Points cut into blocks once and evaluated for several models (the judges' points): each
// evaluation the same bits as the per-point one; non-finite points are not taken.
TEST(BlockFeatures, PointBlocksCutOnceServeEveryModel)
{
    std::mt19937 rng(13);
    std::uniform_real_distribution<float> u(-0.6f, 0.6f);
    std::vector<float> points;
    for (int j = 0; j < 2000; ++j)
        for (int a = 0; a < 3; ++a) points.push_back(u(rng));
    const std::size_t m = points.size() / 3;
    FeatureOptions fo;
    fo.filterVariance = 1e-3f;
    const PointBlocks blocks(points.data(), m, true);
    ASSERT_TRUE(blocks.usable());
    for (int degree : {0, 1, 3}) {
        const GaussianCloud cloud = randomCloud(90, degree, 7u + std::uint32_t(degree), 0.45f, 0.01f, 0.12f);
        const int stride = cloud.shStride();
        std::vector<float> fa(m * std::size_t(stride)), oa(m), fb(fa.size(), -1.0f), ob(m, -1.0f);
        evaluateFeatures(cloud, points.data(), m, fo, fa.data(), oa.data());
        blocks.evaluate(cloud, fo, fb.data(), ob.data());
        EXPECT_EQ(std::memcmp(fa.data(), fb.data(), fa.size() * sizeof(float)), 0) << "degree " << degree;
        EXPECT_EQ(std::memcmp(oa.data(), ob.data(), oa.size() * sizeof(float)), 0) << "degree " << degree;
    }
    points[7] = INFINITY;
    EXPECT_FALSE(PointBlocks(points.data(), m, true).usable());
    EXPECT_FALSE(PointBlocks(points.data(), 0, true).usable());
}
