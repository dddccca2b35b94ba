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
