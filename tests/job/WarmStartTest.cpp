#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include "ChoiceFixture.h"
#include "job/DeformPipeline.h"
#include "job/WarmStart.h"
#include "demo/DemoModels.h"
#include "io/GaussianIO.h"
#include "support/TestSupport.h"

using namespace splatwarp;
using namespace splatwarp::test;

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

TEST(WarmStart, AStartFarAboveTheFrameBeforesFitIsRejectedTiesAreKept)
{
    EXPECT_FALSE(rejectsWarmStart(kWarmEnergyLimit * 100.0, 100.0));
    EXPECT_FALSE(rejectsWarmStart(50.0, 100.0));
    EXPECT_TRUE(rejectsWarmStart(kWarmEnergyLimit * 100.0 * 1.0001, 100.0));
    EXPECT_TRUE(rejectsWarmStart(std::nan(""), 100.0));
}

namespace {

/// A small stripes bar bent by the sample spec, few iterations (about a second a fit).
DeformJobOptions smallBend(const TempDir& dir)
{
    DeformJobOptions o = stripesBend(dir, 1500);
    o.grid.cells = 12;
    o.stage2.iterations = 3;
    o.heldOut.points = 3000;
    o.curveSplit = false; // a split frame starts cold: these tests need the warm start
    o.validatedSplit = false;
    return o;
}

/// Where a frame writes only its fitted model.
FrameOutputs fittedTo(const std::string& path)
{
    FrameOutputs out;
    out.deformed = path;
    return out;
}

} // namespace

TEST(WarmStart, AWarmStartWorseThanTheLimitFallsBackToTheColdStartsBytes)
{
    TempDir dir;
    const DeformJobOptions o = smallBend(dir);
    std::unique_ptr<DeformRest> rest = prepareDeformRest(o, graphOptionsOf(loadDeformSpec(o.specPath), o));
    const DeformSpec spec = loadDeformSpec(o.specPath);
    const nlohmann::json coldReport = runDeformFrame(*rest, spec, o, fittedTo(dir.file("cold.ply"))).toJson();
    ASSERT_FALSE(coldReport["stage2"].contains("start")); // deform's report is unchanged
    const double coldFit = coldReport["stage2"]["bestEnergy"].get<double>();
    // A correction made deliberately wrong: every moving Gaussian's opacity logit pushed far up.
    auto rejectsLikeAnimate = [&](const StageTwoReport& fit) {
        return rejectsWarmStart(fit.energies.front().total, coldFit);
    };
    StageTwoStart wrong{[](const StageOneResult& s1, GaussianCloud& m) {
                            for (std::size_t i = 0; i < m.size(); ++i)
                                if (s1.moving[i]) m.opacities[i] += 6.0f;
                        },
                        rejectsLikeAnimate};
    const nlohmann::json r = runDeformFrame(*rest, spec, o, fittedTo(dir.file("fellBack.ply")), nullptr, wrong).toJson();
    EXPECT_EQ(r["stage2"]["start"], "cold");
    EXPECT_GT(r["stage2"]["warmEnergy"].get<double>(), kWarmEnergyLimit * coldFit);
    EXPECT_EQ(fileBytes(dir.file("fellBack.ply")), fileBytes(dir.file("cold.ply")));
    // A start that is not rejected is fitted once and reported as the warm one.
    StageTwoStart same{[](const StageOneResult&, GaussianCloud&) {}, [](const StageTwoReport&) { return false; }};
    const nlohmann::json k = runDeformFrame(*rest, spec, o, fittedTo(dir.file("kept.ply")), nullptr, same).toJson();
    EXPECT_EQ(k["stage2"]["start"], "warm");
    EXPECT_FALSE(k["stage2"].contains("warmEnergy"));
    EXPECT_EQ(fileBytes(dir.file("kept.ply")), fileBytes(dir.file("cold.ply")));
}
