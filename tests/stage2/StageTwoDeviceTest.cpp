// Device parsing and Stage II dispatch in a CPU-only process (this binary never links the
// CUDA kernels): CUDA requested without support fails clearly, auto runs on the CPU, and a
// registered GPU implementation running out of memory falls back to the CPU under auto only.
#include <gtest/gtest.h>

#include <cstring>
#include <string>

#include "support/FakeCuda.h"
#include "support/TestSupport.h"
#include "core/Device.h"
#include "stage2/StageTwoDevice.h"
#include "stage2/StageTwoTestProblem.h"

using namespace splatwarp;
using namespace splatwarp::test;

namespace {

int gFakeCalls = 0;
StageTwoReport fakeOutOfMemory(GaussianCloud&, const SampleSet&, const std::vector<std::uint8_t>&,
                               const std::vector<std::int32_t>&, const StageTwoOptions&,
                               const std::function<void(int, const GaussianCloud&)>&, int)
{
    ++gFakeCalls;
    throw DeviceMemoryError("CUDA: out of GPU memory for the coverage pairs (1234 bytes)");
}
StageTwoReport fakeSuccess(GaussianCloud&, const SampleSet&, const std::vector<std::uint8_t>&,
                           const std::vector<std::int32_t>&, const StageTwoOptions&,
                           const std::function<void(int, const GaussianCloud&)>&, int)
{
    ++gFakeCalls;
    StageTwoReport r;
    r.movingGaussians = 12345; // marks this fake's report
    return r;
}

RigidStageTwoProblem smallProblem()
{
    StageTwoOptions o;
    o.iterations = 3;
    return rigidStageTwoProblem(12, 0, 7, 0.4f, Mat3d::identity(), Vec3d(0.03, 0, 0), 6, 0.9f, o);
}

/// The problem's options on a device resolved now (after any fake registration).
StageTwoOptions on(const RigidStageTwoProblem& p, Device requested)
{
    StageTwoOptions o = p.options;
    o.device = resolveDevice(requested);
    return o;
}

bool sameParams(const GaussianCloud& a, const GaussianCloud& b)
{
    return a.means == b.means && a.rotations == b.rotations && a.logScales == b.logScales &&
           a.opacities == b.opacities && a.sh == b.sh;
}

} // namespace

TEST(Device, ParseNamesAndRejectOthers)
{
    EXPECT_EQ(parseDevice("auto"), Device::Auto);
    EXPECT_EQ(parseDevice("cpu"), Device::Cpu);
    EXPECT_EQ(parseDevice("cuda"), Device::Cuda);
    for (Device d : {Device::Auto, Device::Cpu, Device::Cuda}) EXPECT_EQ(parseDevice(deviceName(d)), d);
    const std::string e = test::inputErrorMessage([] { parseDevice("gpu"); });
    EXPECT_NE(e.find("'gpu'"), std::string::npos) << e;
    EXPECT_NE(e.find("auto, cpu or cuda"), std::string::npos) << e;
    EXPECT_THROW(parseDevice("CUDA"), InputError);
}

TEST(Device, CudaWithoutSupportFailsClearly)
{
    ASSERT_FALSE(cudaCompiledIn()) << "the CPU test binary must not register CUDA backends";
    EXPECT_EQ(resolveDevice(Device::Auto).device(), Device::Cpu);
    EXPECT_EQ(resolveDevice(Device::Auto).requested(), Device::Auto);
    EXPECT_EQ(resolveDevice(Device::Cpu).device(), Device::Cpu);
    EXPECT_FALSE(resolveDevice(Device::Cpu).cpuFallback());
    EXPECT_EQ(ResolvedDevice().device(), Device::Cpu);
    const std::string e = test::inputErrorMessage([] { resolveDevice(Device::Cuda); });
    EXPECT_NE(e.find("this build has no CUDA support"), std::string::npos) << e;
}

TEST(Device, CudaWithoutGpuFailsClearlyAndAutoUsesCpu)
{
    gFakeCalls = 0;
    FakeCuda fake(noGpu, fakeSuccess);
    EXPECT_TRUE(cudaCompiledIn());
    EXPECT_FALSE(cudaPresent());
    const std::string e = test::inputErrorMessage([] { resolveDevice(Device::Cuda); });
    EXPECT_NE(e.find("no usable CUDA GPU"), std::string::npos) << e;
    const RigidStageTwoProblem p = smallProblem();
    GaussianCloud cloud = p.start;
    const StageTwoReport r = runStageTwo(cloud, p.samples, p.moving, p.cells, on(p, Device::Auto));
    EXPECT_EQ(r.device, Device::Cpu);
    EXPECT_EQ(gFakeCalls, 0);
}

TEST(Device, GpuWithoutCudaStageTwoIsRefusedUnderCudaOnly)
{
    FakeCuda fake(gpu, nullptr); // a probe but no Stage II: a CUDA build without this kernel
    const RigidStageTwoProblem p = smallProblem();
    GaussianCloud cloud = p.start;
    const std::string e = test::inputErrorMessage(
        [&] { runStageTwo(cloud, p.samples, p.moving, p.cells, on(p, Device::Cuda)); });
    EXPECT_NE(e.find("no CUDA Stage II"), std::string::npos) << e;
    EXPECT_TRUE(sameParams(cloud, p.start));
    EXPECT_EQ(runStageTwo(cloud, p.samples, p.moving, p.cells, on(p, Device::Auto)).device, Device::Cpu);
}

TEST(Device, AutoDispatchesToRegisteredCuda)
{
    gFakeCalls = 0;
    FakeCuda fake(gpu, fakeSuccess);
    const RigidStageTwoProblem p = smallProblem();
    GaussianCloud cloud = p.start;
    const StageTwoReport r = runStageTwo(cloud, p.samples, p.moving, p.cells, on(p, Device::Auto));
    EXPECT_EQ(gFakeCalls, 1);
    EXPECT_EQ(r.device, Device::Cuda);
    EXPECT_EQ(r.movingGaussians, 12345u);
    const StageTwoReport c = runStageTwo(cloud, p.samples, p.moving, p.cells, on(p, Device::Cpu));
    EXPECT_EQ(gFakeCalls, 1);
    EXPECT_EQ(c.device, Device::Cpu);
}

TEST(Device, OutOfGpuMemoryFallsBackUnderAutoOnly)
{
    gFakeCalls = 0;
    FakeCuda fake(gpu, fakeOutOfMemory);
    const RigidStageTwoProblem p = smallProblem();
    GaussianCloud reference = p.start, cloud = p.start;
    const StageTwoReport ref = optimiseStageTwo(reference, p.samples, p.moving, p.cells, p.options);
    const StageTwoReport r = runStageTwo(cloud, p.samples, p.moving, p.cells, on(p, Device::Auto));
    EXPECT_EQ(gFakeCalls, 1);
    EXPECT_EQ(r.device, Device::Cpu);
    EXPECT_TRUE(sameParams(cloud, reference));
    EXPECT_EQ(r.energies.back().total, ref.energies.back().total);

    GaussianCloud explicitCuda = p.start;
    try {
        runStageTwo(explicitCuda, p.samples, p.moving, p.cells, on(p, Device::Cuda));
        ADD_FAILURE() << "expected DeviceMemoryError";
    } catch (const DeviceMemoryError& e) {
        EXPECT_NE(std::string(e.what()).find("coverage pairs"), std::string::npos) << e.what();
    }
    EXPECT_EQ(gFakeCalls, 2);
    EXPECT_TRUE(sameParams(explicitCuda, p.start));
}

namespace {

StageTwoReport fakePastIndexLimits(GaussianCloud&, const SampleSet&, const std::vector<std::uint8_t>&,
                                   const std::vector<std::int32_t>&, const StageTwoOptions&,
                                   const std::function<void(int, const GaussianCloud&)>&, int)
{
    ++gFakeCalls;
    throw DeviceLimitError("Stage II coverage has 6300000000 pairs; too many for 32-bit indices");
}

/// Evaluates two iterations of its own run, then runs out of memory (a rebuild that grew).
StageTwoReport fakeEvalThenOutOfMemory(GaussianCloud& cloud, const SampleSet&, const std::vector<std::uint8_t>&,
                                       const std::vector<std::int32_t>&, const StageTwoOptions&,
                                       const std::function<void(int, const GaussianCloud&)>& onEval, int evalEvery)
{
    ++gFakeCalls;
    for (int it = evalEvery; it <= 2 * evalEvery; it += evalEvery)
        if (onEval) onEval(it, cloud);
    throw DeviceMemoryError("CUDA: out of GPU memory for the coverage pairs (99 bytes)");
}

} // namespace

// A count past the GPU's 32-bit indices is no bad input (the CPU's block lists are n^3 times
// shorter): auto runs Stage II on the CPU, cuda fails with the limit and the hint, not as out of memory.
TEST(Device, PastTheGpuIndexLimitsFallsBackUnderAutoOnly)
{
    gFakeCalls = 0;
    FakeCuda fake(gpu, fakePastIndexLimits);
    const RigidStageTwoProblem p = smallProblem();
    GaussianCloud reference = p.start, cloud = p.start;
    optimiseStageTwo(reference, p.samples, p.moving, p.cells, p.options);
    const StageTwoReport r = runStageTwo(cloud, p.samples, p.moving, p.cells, on(p, Device::Auto));
    EXPECT_EQ(gFakeCalls, 1);
    EXPECT_EQ(r.device, Device::Cpu);
    EXPECT_TRUE(sameParams(cloud, reference));

    GaussianCloud explicitCuda = p.start;
    try {
        runStageTwo(explicitCuda, p.samples, p.moving, p.cells, on(p, Device::Cuda));
        ADD_FAILURE() << "expected DeviceLimitError";
    } catch (const DeviceMemoryError& e) {
        ADD_FAILURE() << "a count limit reported as out of memory: " << e.what();
    } catch (const DeviceLimitError& e) {
        const std::string m = e.what();
        EXPECT_NE(m.find("6300000000 pairs"), std::string::npos) << m;
        EXPECT_NE(m.find("--device auto would run Stage II on the CPU"), std::string::npos) << m;
    }
    EXPECT_EQ(gFakeCalls, 2);
    EXPECT_TRUE(sameParams(explicitCuda, p.start));
}

// After a fallback the CPU run starts again at iteration 0: onRestart tells the caller to drop
// what the GPU run's evaluations recorded, so each iteration is recorded once, from the CPU run.
TEST(Device, FallbackRecordsEachEvaluationOnce)
{
    gFakeCalls = 0;
    FakeCuda fake(gpu, fakeEvalThenOutOfMemory);
    RigidStageTwoProblem p = smallProblem();
    p.options.iterations = 4;
    std::vector<int> curve;
    int restarts = 0;
    const auto record = [&](int it, const GaussianCloud&) { curve.push_back(it); };
    GaussianCloud cloud = p.start;
    optimiseStageTwo(cloud, p.samples, p.moving, p.cells, p.options, record, 1);
    const std::vector<int> cpuCurve = curve;
    ASSERT_GE(cpuCurve.size(), 3u) << "premise: the CPU run evaluates more iterations than the fake";
    curve.clear();
    cloud = p.start;
    const StageTwoReport r =
        runStageTwo(cloud, p.samples, p.moving, p.cells, on(p, Device::Auto), record, 1, [&] {
            ++restarts;
            curve.clear();
        });
    EXPECT_EQ(gFakeCalls, 1);
    EXPECT_EQ(r.device, Device::Cpu);
    EXPECT_EQ(restarts, 1);
    EXPECT_EQ(curve, cpuCurve);

    // No GPU evaluation seen (the run failed before any): no restart to report.
    FakeCuda limit(gpu, fakePastIndexLimits);
    restarts = 0;
    curve.clear();
    cloud = p.start;
    runStageTwo(cloud, p.samples, p.moving, p.cells, on(p, Device::Auto), record, 1, [&] { ++restarts; });
    EXPECT_EQ(restarts, 0);
    EXPECT_EQ(curve, cpuCurve);
}
