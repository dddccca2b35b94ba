// The one Stage II loop over a scripted solver: schedule, forced rebuilds, best-iterate keeping
// and what happens when the energy stops being finite.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "core/Error.h"
#include "stage2/StageTwoLoop.h"
#include "stage2/StageTwoParams.h"

using namespace splatwarp;

namespace {

/// A solver whose "parameter" is the iteration count of the steps taken; its energies are scripted.
class ScriptedSolver final : public StageTwoSolver {
public:
    explicit ScriptedSolver(std::vector<double> energies) : mEnergies(std::move(energies)) {}
    Device device() const override { return Device::Cpu; }
    void describe(StageTwoReport& r) const override { r.movingGaussians = 1; }
    void prepare() override {}
    void rebuildCoverage(int iteration, bool) override { rebuilds.push_back(iteration); }
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
    /// The step's first-order decrease is slope x its rate scale (0: none known, the rule's fallback).
    double step(const StageTwoStep& st) override
    {
        steps.push_back(st);
        mState = ++mNext; // every step reaches a new scripted energy, also one taken again
        return slope * double(st.rateScale);
    }
    void saveIterate() override { mKept = mState; }
    void restoreIterate() override { mState = mKept; }
    void writeTo(GaussianCloud& cloud) const override { cloud.opacities.assign(1, float(mState)); }
    StageTwoPhaseTimes times() const override { return {}; }

    std::vector<int> rebuilds;
    std::vector<StageTwoStep> steps;
    bool holds = true;
    double slope = 0;

private:
    std::vector<double> mEnergies;
    int mState = 0, mNext = 0, mKept = -1;
};

/// The loop without step rejection (keepBest only), as before it existed.
StageTwoOptions options(int iterations, int rebuildEvery = 3)
{
    StageTwoOptions o;
    o.iterations = iterations;
    o.rebuildEvery = rebuildEvery;
    o.rejectSteps = false;
    return o;
}

StageTwoOptions rejecting(int iterations, int stallStop = 6)
{
    StageTwoOptions o = options(iterations);
    o.rejectSteps = true;
    o.stallStop = stallStop;
    return o;
}

/// 8 iterations with step rejection over falling energies, so that iterate k is held at
/// iteration k and scores scoreOfState[k] on the held-out points (checked every `every`, early
/// at `early`); `scored` counts the scores taken.
StageTwoReport runOnHeldOutScores(GaussianCloud& cloud, const std::vector<double>& scoreOfState, int every, int early = 2,
                                  int* scored = nullptr)
{
    ScriptedSolver s({10, 9, 8, 7, 6, 5, 4, 3, 2});
    cloud.opacities = {0.0f}; // the start: state 0
    StageTwoOptions o = rejecting(8);
    o.heldOutStop = {[&](const GaussianCloud& m) {
                         if (scored) ++*scored;
                         return scoreOfState.at(std::size_t(m.opacities.at(0)));
                     },
                     every, early};
    return runStageTwoLoop(s, cloud, o);
}

/// A run with step rejection over scripted energies whose steps promise slope x their scale.
struct SlopedRun {
    ScriptedSolver solver;
    StageTwoReport report;
};

SlopedRun runSloped(std::vector<double> energies, double slope, int iterations)
{
    SlopedRun run{ScriptedSolver(std::move(energies)), {}};
    run.solver.slope = slope;
    GaussianCloud cloud;
    run.report = runStageTwoLoop(run.solver, cloud, rejecting(iterations));
    return run;
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

TEST(StageTwoLoop, WithoutAScheduleRebuildsOnlyWhenCoverageStopsHolding)
{
    ScriptedSolver s({5, 4, 3, 2, 1, 0.5, 0.25});
    GaussianCloud cloud;
    StageTwoReport r = runStageTwoLoop(s, cloud, options(6, 0));
    EXPECT_EQ(s.rebuilds, (std::vector<int>{0}));
    EXPECT_EQ(r.coverageForcedRebuilds, 0);
    ScriptedSolver t({5, 4, 3, 2, 1, 0.5, 0.25});
    t.holds = false;
    r = runStageTwoLoop(t, cloud, options(6, 0));
    EXPECT_EQ(t.rebuilds, (std::vector<int>{0, 1, 2, 3, 4, 5, 6}));
    EXPECT_EQ(r.coverageForcedRebuilds, 6);
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

TEST(StageTwoLoop, ARejectedStepIsTakenAgainAtTheParabolasBestLength)
{
    // From 100 a step promising 2 reaches 104: r = -4 / 2, so the parabola's best is 1 / (2 (1 + 2)).
    const SlopedRun run = runSloped({100, 104, 99, 98.5, 98}, 2, 3);
    const ScriptedSolver& s = run.solver;
    const StageTwoReport& r = run.report;
    ASSERT_EQ(s.steps.size(), 3u);
    EXPECT_EQ(s.steps[0].rateScale, 1.0f);
    EXPECT_EQ(s.steps[1].rateScale, float(1.0 / 6.0));
    EXPECT_EQ(s.steps[1].adamStep, s.steps[0].adamStep); // the same Adam step, taken again
    // 104 -> 99 after a step promising 1/3: r = 3, past the parabola's reach: x1.25.
    EXPECT_EQ(s.steps[2].rateScale, float(1.0 / 6.0) * 1.25f);
    EXPECT_EQ(r.rejectedSteps, 1);
    EXPECT_EQ(r.bestEnergy, 98.5);
}

TEST(StageTwoLoop, AnAcceptedStepThatFellShortOfItsPromiseShortensTheNext)
{
    // Each step promises 2 x its scale. 100 -> 99 at scale 1: r = 0.5, best length 1, aim 1.5: x1.25
    // (capped at scale 1). 99 -> 98.9 at scale 1: r = 0.05, best 0.526, aim 0.789.
    const SlopedRun run = runSloped({100, 99, 98.9, 98.8}, 2, 3);
    ASSERT_EQ(run.solver.steps.size(), 3u);
    EXPECT_EQ(run.solver.steps[1].rateScale, 1.0f);
    EXPECT_NEAR(run.solver.steps[2].rateScale, 1.5 / (2.0 * (1.0 - 0.1 / 2.0)), 1e-6);
    EXPECT_EQ(run.report.rejectedSteps, 0);
}

TEST(StageTwoLoop, AdamsFirstStepPromisingTooMuchIsTakenAgainShorter)
{
    // From 100 the first step promises 10 at scale 1: more than 3% of the energy, so it is undone
    // and taken again at the scale that promises 3; no forward pass is spent on it.
    const SlopedRun run = runSloped({100, 150, 90, 89}, 10, 2);
    const ScriptedSolver& s = run.solver;
    const StageTwoReport& r = run.report;
    ASSERT_GE(s.steps.size(), 2u);
    EXPECT_EQ(s.steps[0].rateScale, 1.0f);
    EXPECT_EQ(s.steps[1].rateScale, 0.3f);
    EXPECT_EQ(s.steps[1].adamStep, s.steps[0].adamStep);
    EXPECT_EQ(r.rejectedSteps, 0); // state 1 (150) was never evaluated
    EXPECT_EQ(r.bestEnergy, 89.0);
    // Without step rejection nothing is undone.
    ScriptedSolver t({100, 150, 90});
    t.slope = 10;
    GaussianCloud cloud;
    runStageTwoLoop(t, cloud, options(2));
    EXPECT_EQ(t.steps.size(), 2u);
}

TEST(StageTwoLoop, RejectedStepsAreTakenAgainAtHalfTheRates)
{
    // Without a first-order decrease (the scripted solver's slope 0) the rule halves and regrows.
    // State k has energy E[k]; steps lead to states 1, 2, 3, ... in turn. 5 -> 4 accepted,
    // 6 rejected (back to state 1, rates x0.5), 3 accepted (rates back to 1), 2 accepted.
    ScriptedSolver s({5, 4, 6, 3, 2});
    GaussianCloud cloud;
    const StageTwoReport r = runStageTwoLoop(s, cloud, rejecting(4));
    ASSERT_EQ(s.steps.size(), 4u);
    EXPECT_EQ(s.steps[1].rateScale, 1.0f); // from state 1
    EXPECT_EQ(s.steps[2].rateScale, 0.5f); // state 2 rejected: again from state 1
    EXPECT_EQ(s.steps[2].adamStep, s.steps[1].adamStep); // the same Adam step, taken again
    EXPECT_EQ(s.steps[3].rateScale, 0.5f * 1.25f); // grows back by a quarter
    EXPECT_EQ(s.steps[3].adamStep, s.steps[2].adamStep + 1);
    EXPECT_EQ(r.rejectedSteps, 1);
    EXPECT_EQ(r.bestEnergy, 2.0);
    EXPECT_EQ(cloud.opacities, std::vector<float>{4.0f});
    ASSERT_FALSE(r.energies.empty());
    for (const StageTwoEnergy& e : r.energies) EXPECT_TRUE(e.rejected == (e.total > 5.0)) << e.iteration;
}

TEST(StageTwoLoop, EndsOnTheAcceptedIterateWhenTheLastStepClimbs)
{
    ScriptedSolver s({5, 4, 7});
    GaussianCloud cloud;
    const StageTwoReport r = runStageTwoLoop(s, cloud, rejecting(2));
    EXPECT_EQ(r.bestIteration, 1);
    EXPECT_EQ(cloud.opacities, std::vector<float>{1.0f});
}

TEST(StageTwoLoop, StopsAfterStallStopRejectionsInARow)
{
    // A rigid spec: Stage I is exact, every step climbs. Before the first accepted step the run
    // allows twice stallStop rejections (Adam's first step may need 2^-6 of the rates).
    ScriptedSolver s({1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12});
    GaussianCloud cloud;
    const StageTwoReport r = runStageTwoLoop(s, cloud, rejecting(10, 3));
    EXPECT_EQ(r.stoppedAt, 6);
    EXPECT_EQ(r.stopReason, "steps rejected in a row");
    EXPECT_EQ(r.rejectedSteps, 6);
    EXPECT_EQ(r.bestIteration, 0);
    EXPECT_EQ(cloud.opacities, std::vector<float>{0.0f});
    ASSERT_EQ(s.steps.size(), 6u);
    EXPECT_EQ(s.steps[5].rateScale, 1.0f / 32.0f);

    // One step accepted, then stallStop rejections end the run.
    ScriptedSolver t({5, 4, 6, 7, 8, 9, 10});
    const StageTwoReport q = runStageTwoLoop(t, cloud, rejecting(10, 3));
    EXPECT_EQ(q.stoppedAt, 4);
    EXPECT_EQ(q.rejectedSteps, 3);
    EXPECT_EQ(q.bestIteration, 1);
    EXPECT_EQ(cloud.opacities, std::vector<float>{1.0f});
}

TEST(StageTwoLoop, AFirstStepThatDescendsOnlyAtSmallRatesIsFound)
{
    // The first step climbs at rates 1 ... 2^-4 and descends at 2^-5: stallStop 3 alone would have
    // ended the run after 3 rejections (train-1000 bend --cells 80 needed 2^-6 with stallStop 6).
    ScriptedSolver s({10, 20, 19, 18, 17, 16, 9, 8});
    GaussianCloud cloud;
    const StageTwoReport r = runStageTwoLoop(s, cloud, rejecting(7, 3));
    ASSERT_EQ(s.steps.size(), 7u);
    EXPECT_EQ(s.steps[5].rateScale, 1.0f / 32.0f);
    EXPECT_EQ(r.rejectedSteps, 5);
    EXPECT_EQ(r.stopReason, "");
    EXPECT_EQ(r.bestEnergy, 8.0);
    EXPECT_EQ(cloud.opacities, std::vector<float>{7.0f});
}

TEST(StageTwoLoop, NonFiniteEnergyIsARejectedStep)
{
    const double nan = std::numeric_limits<double>::quiet_NaN();
    ScriptedSolver s({5, nan, 4, 3});
    GaussianCloud cloud;
    const StageTwoReport r = runStageTwoLoop(s, cloud, rejecting(3));
    EXPECT_EQ(r.rejectedSteps, 1);
    EXPECT_EQ(r.bestEnergy, 3.0);
    EXPECT_EQ(cloud.opacities, std::vector<float>{3.0f});
}

TEST(StageTwoLoop, StopsWhenTheEnergyStalls)
{
    // Falls by 10% per step, then by ~0.1%: with a 1% tolerance over 2 iterations the run stops
    // at the first iteration less than 1% below the one 2 before (81 -> 80.8 at iteration 4).
    ScriptedSolver s({100, 90, 81, 80.9, 80.8, 80.7, 80.6, 80.5});
    StageTwoOptions o = rejecting(7);
    o.stallTolerance = 0.01f;
    o.stallWindow = 2;
    GaussianCloud cloud;
    const StageTwoReport r = runStageTwoLoop(s, cloud, o);
    EXPECT_EQ(r.stoppedAt, 4);
    EXPECT_EQ(r.stopReason, "the energy stalled");
    EXPECT_EQ(r.bestEnergy, 80.8);
    EXPECT_EQ(cloud.opacities, std::vector<float>{4.0f});
    StageTwoOptions off = rejecting(7);
    ScriptedSolver t({100, 90, 81, 80.9, 80.8, 80.7, 80.6, 80.5});
    const StageTwoReport ran = runStageTwoLoop(t, cloud, off);
    EXPECT_EQ(ran.stoppedAt, -1);
    EXPECT_EQ(ran.stopReason, "");
}

TEST(StageTwoLoop, AutoIterationsStopOnAStallBeforeTheCapAndRunOnWhileTheEnergyFalls)
{
    StageTwoOptions o;
    o.setAutoIterations();
    ASSERT_GT(o.stallTolerance, 0.0f);
    const int cap = o.iterations;
    // Falls by 1% a step for 40 steps, then by 0.05 x the tolerance per step: held energies
    // e(40 + k) = e40 (1 - 0.05 tol k). The first iteration i with e(i - w) - e(i) < tol e(i - w)
    // is the first whose window lies in the slow part (0.05 tol w < tol for w = 10): i = 40 + w.
    std::vector<double> stalling(std::size_t(cap) + 1);
    const double tol = double(o.stallTolerance);
    for (std::size_t i = 0; i < stalling.size(); ++i)
        stalling[i] = i <= 40 ? 1000.0 * std::pow(0.99, double(i))
                              : stalling[40] * (1.0 - 0.05 * tol * double(i - 40));
    ScriptedSolver s(stalling);
    GaussianCloud cloud;
    const StageTwoReport r = runStageTwoLoop(s, cloud, o);
    EXPECT_EQ(r.stoppedAt, 40 + o.stallWindow);
    EXPECT_LT(r.stoppedAt, cap);
    EXPECT_EQ(r.bestEnergy, stalling[std::size_t(r.stoppedAt)]);
    // Falling by 0.05% a step (0.5% over 10 iterations, five times the tolerance): no stall, the
    // run takes every iteration up to the cap.
    std::vector<double> falling(std::size_t(cap) + 1);
    for (std::size_t i = 0; i < falling.size(); ++i) falling[i] = 1000.0 * std::pow(1.0 - 0.5 * tol, double(i));
    ScriptedSolver t(falling);
    const StageTwoReport all = runStageTwoLoop(t, cloud, o);
    EXPECT_EQ(all.stoppedAt, -1);
    EXPECT_EQ(all.bestIteration, cap);
    EXPECT_EQ(t.steps.size(), std::size_t(cap));
}

TEST(StageTwoLoop, AutoIterationsKeepTheDefaultRunsPositionSchedule)
{
    // The position rate decays over a default run's iterations, then stays at the end rate, so
    // the first steps of an auto run are those of a default run.
    StageTwoOptions plain, automatic;
    automatic.setAutoIterations();
    ASSERT_GT(automatic.iterations, plain.iterations);
    for (int it = 0; it < plain.iterations; ++it)
        EXPECT_EQ(stageTwoPositionRate(automatic, it, 2.0f), stageTwoPositionRate(plain, it, 2.0f)) << it;
    const float end = stageTwoPositionRate(plain, plain.iterations - 1, 2.0f);
    EXPECT_FLOAT_EQ(end, plain.lrPositionEnd * 2.0f);
    for (int it = plain.iterations; it <= automatic.iterations; it += 50) EXPECT_EQ(stageTwoPositionRate(automatic, it, 2.0f), end) << it;
    // A number after auto drops its schedule: the rate decays over the run again.
    StageTwoOptions again = automatic;
    again.iterations = 50;
    again.scheduleIterations = 0;
    EXPECT_EQ(stageTwoPositionRate(again, 49, 2.0f), end);
}

TEST(StageTwoLoop, StopsWhenTheHeldOutScoreStopsFalling)
{
    // Energies fall all the way; the held-out score (here: of the written "parameter", the state)
    // falls from the start's at the check of iteration 2 and rises at iteration 4: the run stops
    // there, holding iteration 4's iterate, and records each check, the start's first.
    ScriptedSolver s({10, 9, 8, 7, 6, 5, 4, 3, 2});
    GaussianCloud cloud;
    cloud.opacities = {0.0f}; // the start: state 0
    StageTwoOptions o = rejecting(8);
    const std::vector<double> scoreOfState = {0.9, 0, 0.5, 0, 0.7, 0, 0.2, 0, 0.1};
    int scored = 0;
    o.heldOutStop = {[&](const GaussianCloud& m) {
                         ++scored;
                         return scoreOfState[std::size_t(m.opacities.at(0))];
                     },
                     2};
    const StageTwoReport r = runStageTwoLoop(s, cloud, o);
    EXPECT_EQ(r.stoppedAt, 4);
    EXPECT_EQ(r.stopReason, "the validation score rose");
    EXPECT_EQ(scored, 3);
    ASSERT_EQ(r.heldOutChecks.size(), 3u);
    EXPECT_EQ(r.heldOutChecks[0], (std::pair<int, double>{0, 0.9}));
    EXPECT_EQ(r.heldOutChecks[1], (std::pair<int, double>{2, 0.5}));
    EXPECT_EQ(r.heldOutChecks[2], (std::pair<int, double>{4, 0.7}));
    EXPECT_EQ(cloud.opacities, std::vector<float>{4.0f});
    EXPECT_EQ(r.bestIteration, 4);
    // A rise within `rise` (1%) of the last check goes on; the next one past it stops.
    ScriptedSolver t({10, 9, 8, 7, 6, 5, 4, 3, 2});
    const std::vector<double> flat = {0.9, 0, 0.5, 0, 0.5049, 0, 0.51, 0, 0.1};
    o.heldOutStop.score = [&](const GaussianCloud& m) { return flat[std::size_t(m.opacities.at(0))]; };
    cloud.opacities = {0.0f};
    EXPECT_EQ(runStageTwoLoop(t, cloud, o).stoppedAt, 6);
}

TEST(StageTwoLoop, AFitWorseOnHeldOutPointsThanItsStartStopsAtTheFirstCheck)
{
    // Guitar's shape: the energy falls while the held-out score is far above the start's (+20%)
    // from the first check on. The start is the first check's reference, so the run stops at
    // iteration 2, not at the first rise between two later checks.
    ScriptedSolver s({10, 9, 8, 7, 6, 5, 4, 3, 2});
    GaussianCloud cloud;
    cloud.opacities = {0.0f};
    StageTwoOptions o = rejecting(8);
    const std::vector<double> scoreOfState = {0.5, 0, 0.6, 0, 0.55, 0, 0.7, 0, 0.1};
    o.heldOutStop = {[&](const GaussianCloud& m) { return scoreOfState[std::size_t(m.opacities.at(0))]; }, 2};
    const StageTwoReport r = runStageTwoLoop(s, cloud, o);
    EXPECT_EQ(r.stoppedAt, 2);
    ASSERT_EQ(r.heldOutChecks.size(), 2u);
    EXPECT_EQ(r.heldOutChecks[0], (std::pair<int, double>{0, 0.5}));
    EXPECT_EQ(cloud.opacities, std::vector<float>{2.0f});
    // Within `riseFromStart` (15%) of the start it goes on; later checks keep `rise` (1%).
    ScriptedSolver t({10, 9, 8, 7, 6, 5, 4, 3, 2});
    const std::vector<double> level = {0.5, 0, 0.55, 0, 0.4, 0, 0.41, 0, 0.1};
    o.heldOutStop.score = [&](const GaussianCloud& m) { return level[std::size_t(m.opacities.at(0))]; };
    cloud.opacities = {0.0f};
    EXPECT_EQ(runStageTwoLoop(t, cloud, o).stoppedAt, 6);
}

TEST(StageTwoLoop, AFitFarWorseThanItsStartAfterItsFirstStepsStopsThere)
{
    // Dense stripes' shape (200k Gaussians, twist: +4.7% after one step, +40% after two): more
    // than `riseFromStart` (15%) above the start at the early check (iteration 2, before the
    // first regular one at 3) stops there; a smaller rise goes on, and the regular check is
    // still compared with the start.
    GaussianCloud cloud;
    const StageTwoReport steep = runOnHeldOutScores(cloud, {0.5, 0, 0.6, 0, 0, 0, 0, 0, 0}, 3, 2);
    EXPECT_EQ(steep.stoppedAt, 2);
    EXPECT_EQ(steep.stopReason, "the validation score rose");
    EXPECT_EQ(steep.heldOutChecks.size(), 2u);
    EXPECT_EQ(cloud.opacities, std::vector<float>{2.0f});
    int scored = 0; // no early check: scored at 0, 3, 6
    EXPECT_EQ(runOnHeldOutScores(cloud, {0.5, 0, 0.6, 0.3, 0, 0, 0.3, 0, 0}, 3, 0, &scored).stoppedAt, -1);
    EXPECT_EQ(scored, 3);
    EXPECT_EQ(runOnHeldOutScores(cloud, {0.5, 0, 0.55, 0.57, 0, 0, 0.3, 0, 0}, 3, 2).stoppedAt, -1);
    EXPECT_EQ(runOnHeldOutScores(cloud, {0.5, 0, 0.55, 0.6, 0, 0, 0.3, 0, 0}, 3, 2).stoppedAt, 3); // > 0.5 x 1.15, < 0.55 x 1.15
}

TEST(StageTwoLoop, AFitThatStaysAboveItsStartStopsAtTheSecondCheck)
{
    // The dense spot's shape: +12% at the first check (within riseFromStart), then flat. At
    // that pace it cannot be back at the start's score by the end, so the run stops at the
    // second check (iteration 4 of 8), though the score did not rise by `rise` (1%).
    GaussianCloud cloud;
    const auto run = [&](const std::vector<double>& scoreOfState) { return runOnHeldOutScores(cloud, scoreOfState, 2); };
    const StageTwoReport flat = run({0.5, 0, 0.56, 0, 0.5605, 0, 0.5, 0, 0.1});
    EXPECT_EQ(flat.stoppedAt, 4);
    EXPECT_EQ(flat.stopReason, "the validation score stays above the start's");
    EXPECT_EQ(cloud.opacities, std::vector<float>{4.0f});
    // Falling: 0.53 at 4, at 0.02 per iteration, would be at 0.45 by 8, and 0.51 at 6 at 0.49...
    EXPECT_EQ(run({0.5, 0, 0.57, 0, 0.53, 0, 0.51, 0, 0.1}).stoppedAt, -1);
    // ...but 0.52 at 6, at 0.005 per iteration, only at 0.51.
    EXPECT_EQ(run({0.5, 0, 0.57, 0, 0.53, 0, 0.52, 0, 0.1}).stoppedAt, 6);
    // The playbot-31k squash's slow start (+5%, then falling fast enough) runs to the end, and
    // a fit below its start is left to the `rise` rule.
    EXPECT_EQ(run({0.5, 0, 0.525, 0, 0.51, 0, 0.504, 0, 0.1}).stoppedAt, -1);
    EXPECT_EQ(run({0.5, 0, 0.45, 0, 0.452, 0, 0.454, 0, 0.1}).stoppedAt, -1);
}

TEST(StageTwoLoop, AHeldOutScoreThatKeepsFallingRunsEveryIteration)
{
    ScriptedSolver s({10, 9, 8, 7, 6, 5, 4});
    GaussianCloud cloud;
    cloud.opacities = {0.0f};
    StageTwoOptions o = rejecting(6);
    o.heldOutStop = {[](const GaussianCloud& m) { return 1.0 / (1.0 + m.opacities.at(0)); }, 2};
    const StageTwoReport r = runStageTwoLoop(s, cloud, o);
    EXPECT_EQ(r.stoppedAt, -1);
    EXPECT_EQ(r.heldOutChecks.size(), 3u); // 0, 2 and 4; none at the last iteration, which ends the run anyway
    EXPECT_EQ(cloud.opacities, std::vector<float>{6.0f});
    // every = 0 never scores
    ScriptedSolver t({10, 9, 8, 7});
    o.iterations = 3;
    o.heldOutStop = {[](const GaussianCloud&) -> double { throw Error("scored"); }, 0};
    EXPECT_NO_THROW(runStageTwoLoop(t, cloud, o));
}
