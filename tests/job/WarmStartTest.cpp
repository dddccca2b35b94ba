#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include "WarmStart.h"
#include "demo/DemoModels.h"

using namespace splatwarp;

TEST(WarmStart, ACorrectionCarriedOntoItsOwnStageOneModelGivesTheFit)
{
    DemoModelOptions so;
    so.count = 200;
    const GaussianCloud stage1 = makeDemoModel("stripes", so);
    GaussianCloud fitted = stage1;
    for (std::size_t i = 0; i < fitted.means.size(); ++i) fitted.means[i] += 0.01f * float(i % 7);
    for (std::size_t i = 0; i < fitted.sh.size(); ++i) fitted.sh[i] -= 0.02f * float(i % 5);
    for (std::size_t i = 0; i < fitted.size(); ++i) {
        fitted.opacities[i] += 0.3f;
        fitted.logScales[3 * i] -= 0.1f;
        fitted.rotations[4 * i + 1] += 0.2f; // a turn, left unnormalised as Adam leaves it
    }
    const StageTwoCorrection c = stageTwoCorrection(stage1, fitted);
    std::vector<std::uint8_t> moving(stage1.size(), 1);
    moving[3] = 0;
    GaussianCloud start = stage1;
    applyCorrection(c, moving, start);
    for (std::size_t i = 0; i < start.size(); ++i) {
        const GaussianCloud& want = moving[i] ? fitted : stage1;
        for (int k = 0; k < 3; ++k) {
            EXPECT_NEAR(start.means[3 * i + k], want.means[3 * i + k], 1e-5) << i;
            EXPECT_NEAR(start.logScales[3 * i + k], want.logScales[3 * i + k], 1e-5) << i;
        }
        EXPECT_NEAR(start.opacities[i], want.opacities[i], 1e-5) << i;
        // Same rotation: unit quaternions equal up to sign.
        double dot = 0, na = 0, nb = 0;
        for (int k = 0; k < 4; ++k) {
            dot += double(start.rotations[4 * i + k]) * want.rotations[4 * i + k];
            na += double(start.rotations[4 * i + k]) * start.rotations[4 * i + k];
            nb += double(want.rotations[4 * i + k]) * want.rotations[4 * i + k];
        }
        EXPECT_NEAR(std::abs(dot) / std::sqrt(na * nb), 1.0, 1e-6) << i;
    }
    const std::size_t stride = std::size_t(stage1.shCoeffs()) * 3;
    for (std::size_t k = 0; k < stride; ++k) {
        EXPECT_NEAR(start.sh[stride * 5 + k], fitted.sh[stride * 5 + k], 1e-5);
        EXPECT_EQ(start.sh[stride * 3 + k], stage1.sh[stride * 3 + k]);
    }
}

TEST(WarmStart, OddFramesStartWarmAndShardsTakeContiguousRangesOfWholePairs)
{
    EXPECT_FALSE(startsWarm(0));
    EXPECT_TRUE(startsWarm(1));
    EXPECT_FALSE(startsWarm(22));
    EXPECT_TRUE(startsWarm(23));
    auto shard = [](int i, int n) {
        Shard s;
        s.index = i;
        s.count = n;
        return s;
    };
    const std::vector<int> ten = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9}; // pairs 0..4
    EXPECT_EQ(warmShardFrames(ten, shard(0, 3)), (std::vector<int>{0, 1}));
    EXPECT_EQ(warmShardFrames(ten, shard(1, 3)), (std::vector<int>{2, 3, 4, 5}));
    EXPECT_EQ(warmShardFrames(ten, shard(2, 3)), (std::vector<int>{6, 7, 8, 9}));
    EXPECT_EQ(warmShardFrames(ten, shard(0, 1)), ten);
    // --frames 3-9: frame 3 is alone in its pair; a shard may get nothing.
    const std::vector<int> range = {3, 4, 5, 6, 7, 8, 9};
    EXPECT_EQ(warmShardFrames(range, shard(0, 2)), (std::vector<int>{3, 4, 5}));
    EXPECT_EQ(warmShardFrames(range, shard(1, 2)), (std::vector<int>{6, 7, 8, 9}));
    std::set<int> all;
    for (int i = 0; i < 6; ++i)
        for (int f : warmShardFrames(range, shard(i, 6))) EXPECT_TRUE(all.insert(f).second) << f;
    EXPECT_EQ(all.size(), range.size());
}
