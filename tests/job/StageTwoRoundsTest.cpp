// Stage II in rounds (job/StageTwoRounds.h) over a fake GPU that takes the first round and runs
// out of memory in the second: the report lists each round's device, and the second round's
// GPU evaluations are dropped before its CPU run records them again.
#include <gtest/gtest.h>

#include <utility>
#include <vector>

#include "job/StageTwoRounds.h"
#include "stage2/StageTwoTestProblem.h"
#include "support/FakeCuda.h"

using namespace splatwarp;
using namespace splatwarp::test;

namespace {

int gCalls = 0;

/// Round 1: evaluates its iterations and succeeds (cloud untouched). Round 2: evaluates one
/// iteration, then out of GPU memory.
StageTwoReport fakeSecondRoundOutOfMemory(GaussianCloud& cloud, const SampleSet&, const std::vector<std::uint8_t>&,
                                          const std::vector<std::int32_t>&, const StageTwoOptions& o,
                                          const std::function<void(int, const GaussianCloud&)>& onEval, int evalEvery)
{
    const bool first = gCalls++ == 0;
    for (int it = evalEvery; it <= (first ? o.iterations : evalEvery); it += evalEvery)
        if (onEval) onEval(it, cloud);
    if (!first) throw DeviceMemoryError("CUDA: out of GPU memory for the split model (7 bytes)");
    StageTwoReport r;
    r.energies.push_back({});
    return r;
}

} // namespace

TEST(StageTwoRounds, EachRoundsDeviceAndOneEvaluationPerIteration)
{
    gCalls = 0;
    FakeCuda fake(gpu, fakeSecondRoundOutOfMemory);
    RigidStageTwoProblem p = rigidStageTwoProblem(12, 0, 7, 0.4f, Mat3d::identity(), Vec3d(0.03, 0, 0), 6, 0.9f);
    p.options.iterations = 6;
    p.options.stallTolerance = 0; // every iteration runs, so the CPU round evaluates all of its own
    p.options.device = resolveDevice(Device::Auto);
    DensifyJobOptions d;
    d.split = true;
    d.splitAfter = 0.5f; // rounds of 3 and 3 iterations
    std::vector<std::pair<int, Device>> curve;
    Device evaluating = Device::Cuda;
    const auto record = [&](int it, const GaussianCloud&) { curve.push_back({it, evaluating}); };
    std::vector<int> drops;
    DensifyCounts counts;
    GaussianCloud cloud = p.start;
    const StageTwoReport r = fitInRounds(cloud, p.samples, p.moving, p.cells, p.options, d, record, 1, counts,
                                         [&](int after) {
                                             drops.push_back(after);
                                             evaluating = Device::Cpu;
                                             while (!curve.empty() && curve.back().first > after) curve.pop_back();
                                         });
    EXPECT_EQ(gCalls, 2);
    EXPECT_EQ(r.roundDevices, (std::vector<Device>{Device::Cuda, Device::Cpu}));
    EXPECT_EQ(devicesName(r), "cuda+cpu");
    EXPECT_EQ(drops, (std::vector<int>{3}));
    const std::vector<std::pair<int, Device>> expected = {{1, Device::Cuda}, {2, Device::Cuda}, {3, Device::Cuda},
                                                          {4, Device::Cpu},  {5, Device::Cpu},  {6, Device::Cpu}};
    EXPECT_EQ(curve, expected);
}

TEST(StageTwoRounds, OneDeviceIsNamedOnce)
{
    StageTwoReport r;
    r.device = Device::Cuda;
    EXPECT_EQ(devicesName(r), "cuda");
    r.roundDevices = {Device::Cpu, Device::Cpu};
    EXPECT_EQ(devicesName(r), "cpu");
}

// The one round loop (stage2/Rounds.h): a round of 0 iterations is not run but the step after it
// is, the merged report offsets the later round's iterations, and only deform's plan runs an empty
// last round when nothing ran.
TEST(StageTwoRounds, EmptyRoundsAreSkippedBetweenStepsStillRunAndIterationsAreOffset)
{
    RigidStageTwoProblem p = rigidStageTwoProblem(12, 0, 7, 0.4f, Mat3d::identity(), Vec3d(0.03, 0, 0), 6, 0.9f);
    p.options.stallTolerance = 0;
    p.options.device = resolveDevice(Device::Cpu);
    std::vector<int> betweenAfter;
    std::vector<int> evaluated;
    GaussianCloud cloud = p.start;
    FitState state{cloud, p.moving, p.cells};
    RoundsPlan plan;
    plan.iterations = {0, 2, 3};
    plan.between = [&](int round) { betweenAfter.push_back(round); };
    plan.onEval = [&](int it, const GaussianCloud&) { evaluated.push_back(it); };
    plan.evalEvery = 1;
    const RoundsReport r = fitRounds(state, p.samples, p.options, plan);
    EXPECT_EQ(r.rounds.size(), 2u);
    EXPECT_EQ(betweenAfter, (std::vector<int>{0, 1}));
    EXPECT_EQ(evaluated, (std::vector<int>{1, 2, 3, 4, 5}));
    EXPECT_EQ(r.merged.roundDevices, (std::vector<Device>{Device::Cpu, Device::Cpu}));
    ASSERT_EQ(r.merged.energies.size(), r.rounds[0].energies.size() + r.rounds[1].energies.size());
    EXPECT_EQ(r.merged.energies.back().iteration, r.rounds[1].energies.back().iteration + 2);

    plan.iterations = {0, 0};
    betweenAfter.clear();
    EXPECT_TRUE(fitRounds(state, p.samples, p.options, plan).rounds.empty()); // from-vdb --iterations 0
    EXPECT_EQ(betweenAfter, (std::vector<int>{0}));
    plan.atLeastOne = true; // deform: the last round runs so the report has a fit
    EXPECT_EQ(fitRounds(state, p.samples, p.options, plan).rounds.size(), 1u);
}
