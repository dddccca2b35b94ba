// The one Stage II loop over a scripted solver: schedule, forced rebuilds, best-iterate keeping
// and what happens when the energy stops being finite.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "core/Error.h"
#include "stage2/StageTwoLoop.h"

using namespace splatwarp;

namespace {

/// A solver whose "parameter" is the iteration count of the steps taken; its energies are scripted.
class ScriptedSolver final : public StageTwoSolver {
public:
    explicit ScriptedSolver(std::vector<double> energies) : mEnergies(std::move(energies)) {}
    const char* device() const override { return "script"; }
    void describe(StageTwoReport& r) const override { r.movingGaussians = 1; }
    void prepare() override {}
    void rebuildCoverage(int iteration) override { rebuilds.push_back(iteration); }
    bool coverageHolds() override { return holds; }
    std::uint64_t coveragePairs() const override { return 0; }
    StageTwoEnergy forward(int iteration, std::uint64_t& pairs) override
    {
        pairs = 1;
        StageTwoEnergy e;
        e.iteration = iteration;
        e.total = e.opacity = mEnergies[std::size_t(mState)];
        return e;
    }
    void backward() override {}
    void step(int) override { ++mState; }
    void saveBest() override { mBest = mState; }
    void restoreBest() override { mState = mBest; }
    void writeTo(GaussianCloud& cloud) const override { cloud.opacities.assign(1, float(mState)); }
    StageTwoPhaseTimes times() const override { return {}; }

    std::vector<int> rebuilds;
    bool holds = true;

private:
    std::vector<double> mEnergies;
    int mState = 0, mBest = -1;
};

StageTwoOptions options(int iterations, int rebuildEvery = 3)
{
    StageTwoOptions o;
    o.iterations = iterations;
    o.rebuildEvery = rebuildEvery;
    return o;
}

} // namespace

TEST(StageTwoLoop, KeepsTheLowestEnergyIterate)
{
    ScriptedSolver s({5, 4, 2, 3, 6});
    GaussianCloud cloud;
    const StageTwoReport r = runStageTwoLoop(s, cloud, options(4));
    EXPECT_EQ(r.bestIteration, 2);
    EXPECT_EQ(r.bestEnergy, 2.0);
    EXPECT_EQ(cloud.opacities, std::vector<float>{2.0f});
    EXPECT_EQ(s.rebuilds, (std::vector<int>{0, 3}));
    EXPECT_EQ(r.coverageRebuilds, 2);
    EXPECT_EQ(r.pairsPerIteration.size(), 4u);
}

TEST(StageTwoLoop, RebuildsWhenCoverageStopsHolding)
{
    ScriptedSolver s({5, 4, 3, 2, 1});
    s.holds = false;
    GaussianCloud cloud;
    const StageTwoReport r = runStageTwoLoop(s, cloud, options(4));
    EXPECT_EQ(s.rebuilds, (std::vector<int>{0, 1, 2, 3, 4}));
    EXPECT_EQ(r.coverageForcedRebuilds, 3); // 1, 2, 4; 0 and 3 are scheduled
    EXPECT_EQ(cloud.opacities, std::vector<float>{4.0f});
}

TEST(StageTwoLoop, NonFiniteStartIsAnInputError)
{
    ScriptedSolver s({std::numeric_limits<double>::quiet_NaN(), 1.0});
    GaussianCloud cloud;
    EXPECT_THROW(runStageTwoLoop(s, cloud, options(1)), InputError);
}

TEST(StageTwoLoop, DivergenceStopsWithTheBestIterate)
{
    const double nan = std::numeric_limits<double>::quiet_NaN();
    ScriptedSolver s({5, 4, nan, nan, nan});
    GaussianCloud cloud;
    const StageTwoReport r = runStageTwoLoop(s, cloud, options(4));
    EXPECT_EQ(r.bestIteration, 1);
    EXPECT_EQ(cloud.opacities, std::vector<float>{1.0f}); // never the never-written snapshot
    StageTwoOptions plain = options(4);
    plain.keepBest = false;
    ScriptedSolver t({5, 4, nan, nan, nan});
    EXPECT_THROW(runStageTwoLoop(t, cloud, plain), Error);
}
