// Stage I update and warping dispatch in a CPU-only process (this binary never links the CUDA
// kernels): CUDA requested without support fails clearly, auto runs on the CPU, and a registered
// GPU implementation running out of memory falls back to the CPU under auto only.
#include <gtest/gtest.h>

#include <memory>

#include "core/Device.h"
#include "deform/StageOneDevice.h"
#include "deform/WarpDevice.h"
#include "demo/DemoModels.h"

using namespace splatwarp;

namespace {

bool gpu() { return true; }

int gApplyCalls = 0;

/// An engine whose update runs out of GPU memory, or returns a marked result.
class FakeEngine : public StageOneEngine {
public:
    explicit FakeEngine(bool outOfMemory) : mOutOfMemory(outOfMemory) {}
    StageOneResult apply(const std::vector<NodeAffine>&, const std::vector<std::uint8_t>&) override
    {
        ++gApplyCalls;
        if (mOutOfMemory) throw DeviceMemoryError("CUDA: out of GPU memory for Stage I SH (99 bytes)");
        StageOneResult r;
        r.movingCount = 424242; // marks this fake's result
        return r;
    }

private:
    bool mOutOfMemory;
};

std::unique_ptr<StageOneEngine> oomOnApply(const GaussianCloud&, const StageOneRig&, std::size_t, const StageOneOptions&)
{
    return std::make_unique<FakeEngine>(true);
}
std::unique_ptr<StageOneEngine> oomOnUpload(const GaussianCloud&, const StageOneRig&, std::size_t, const StageOneOptions&)
{
    throw DeviceMemoryError("CUDA: out of GPU memory for Stage I rest SH (99 bytes)");
}
std::unique_ptr<StageOneEngine> works(const GaussianCloud&, const StageOneRig&, std::size_t, const StageOneOptions&)
{
    return std::make_unique<FakeEngine>(false);
}

void oomWarp(const DeformationGraph&, const NodeTransforms&, const float*, std::size_t, float*, float*, bool)
{
    throw DeviceMemoryError("CUDA: out of GPU memory for warped points (99 bytes)");
}

/// Registers fakes for one test and always restores the CPU-only state.
struct FakeCuda {
    FakeCuda(StageOneEngineFactory stageOne, WarpPointsFunction warp = nullptr)
    {
        registerCudaProbe(&gpu);
        registerStageOneCuda(stageOne);
        registerWarpCuda(warp, nullptr);
    }
    ~FakeCuda()
    {
        registerCudaProbe(nullptr);
        registerStageOneCuda(nullptr);
        registerWarpCuda(nullptr, nullptr);
    }
};

struct Problem {
    GaussianCloud rest = makeDemoModel("stripes", DemoModelOptions{1500, 1});
    Deformation d;
    StageOneRig rig;
    Problem()
    {
        DeformSpec spec = loadDeformSpec(std::string(SPLATWARP_SOURCE_DIR) + "/samples/specs/bend.json");
        spec.graph.nodes = 48;
        d = solveDeformation(rest, spec);
        rig = prepareStageOne(rest, d.graph);
    }
    StageOneResult cpu() const { return applyStageOneCpu(rest, rig, d.graph, d.transforms, d.nodeMoving); }
};

bool sameModel(const GaussianCloud& a, const GaussianCloud& b)
{
    return a.means == b.means && a.rotations == b.rotations && a.logScales == b.logScales && a.sh == b.sh;
}

/// Stage I options on a device resolved now (after any fake registration).
StageOneOptions on(Device requested)
{
    StageOneOptions o;
    o.device = resolveDevice(requested);
    return o;
}

} // namespace

TEST(StageOneDevice, CpuAndAutoWithoutGpuRunTheCpuPath)
{
    const Problem p;
    const StageOneResult ref = p.cpu();
    for (Device dev : {Device::Cpu, Device::Auto}) {
        StageOneUpdater u(p.rest, p.rig, p.d.graph, on(dev));
        EXPECT_EQ(u.device(), Device::Cpu);
        const StageOneResult r = u.apply(p.d.transforms, p.d.nodeMoving);
        EXPECT_EQ(r.device, Device::Cpu);
        EXPECT_TRUE(sameModel(r.deformed, ref.deformed));
        EXPECT_EQ(r.moving, ref.moving);
    }
    EXPECT_THROW(on(Device::Cuda), InputError);
    // A GPU but no CUDA engine registered: refused under Cuda, the CPU under Auto.
    const FakeCuda probeOnly(nullptr);
    EXPECT_THROW(StageOneUpdater(p.rest, p.rig, p.d.graph, on(Device::Cuda)), InputError);
    EXPECT_EQ(StageOneUpdater(p.rest, p.rig, p.d.graph, on(Device::Auto)).device(), Device::Cpu);
}

TEST(StageOneDevice, OutOfMemoryFallsBackUnderAutoOnly)
{
    const Problem p;
    const StageOneResult ref = p.cpu();
    {
        const FakeCuda fake(&oomOnApply);
        gApplyCalls = 0;
        StageOneUpdater autoU(p.rest, p.rig, p.d.graph, on(Device::Auto));
        EXPECT_EQ(autoU.device(), Device::Cuda);
        const StageOneResult r = autoU.apply(p.d.transforms, p.d.nodeMoving);
        EXPECT_EQ(gApplyCalls, 1);
        EXPECT_EQ(r.device, Device::Cpu);
        EXPECT_TRUE(sameModel(r.deformed, ref.deformed));
        EXPECT_EQ(autoU.device(), Device::Cpu); // later steps stay on the CPU
        StageOneUpdater cudaU(p.rest, p.rig, p.d.graph, on(Device::Cuda));
        EXPECT_THROW(cudaU.apply(p.d.transforms, p.d.nodeMoving), DeviceMemoryError);
    }
    {
        const FakeCuda fake(&oomOnUpload);
        StageOneUpdater autoU(p.rest, p.rig, p.d.graph, on(Device::Auto));
        EXPECT_EQ(autoU.device(), Device::Cpu);
        EXPECT_TRUE(sameModel(autoU.apply(p.d.transforms, p.d.nodeMoving).deformed, ref.deformed));
        EXPECT_THROW(StageOneUpdater(p.rest, p.rig, p.d.graph, on(Device::Cuda)), DeviceMemoryError);
    }
    {
        const FakeCuda fake(&works);
        StageOneUpdater u(p.rest, p.rig, p.d.graph, on(Device::Cuda));
        const StageOneResult r = u.apply(p.d.transforms, p.d.nodeMoving);
        EXPECT_EQ(r.movingCount, 424242u);
        EXPECT_EQ(r.device, Device::Cuda);
        // Mismatched transforms are rejected before reaching the device.
        EXPECT_THROW(u.apply(NodeTransforms::identity(3), p.d.nodeMoving), InputError);
    }
}

TEST(WarpDevice, OutOfMemoryFallsBackUnderAutoOnly)
{
    const Problem p;
    const std::size_t n = p.rest.size();
    std::vector<float> ref(3 * n), refRot(9 * n), got(3 * n), gotRot(9 * n);
    warpPoints(p.d.graph, p.d.transforms, p.rest.means.data(), n, ref.data(), refRot.data());
    EXPECT_EQ(warpPointsOn(p.d.graph, p.d.transforms, p.rest.means.data(), n, got.data(), gotRot.data(),
                           {resolveDevice(Device::Auto)}),
              Device::Cpu);
    EXPECT_EQ(got, ref);
    const FakeCuda fake(&works, &oomWarp);
    std::fill(got.begin(), got.end(), 0.0f);
    EXPECT_EQ(warpPointsOn(p.d.graph, p.d.transforms, p.rest.means.data(), n, got.data(), gotRot.data(),
                           {resolveDevice(Device::Auto)}),
              Device::Cpu);
    EXPECT_EQ(got, ref);
    EXPECT_EQ(gotRot, refRot);
    EXPECT_THROW(warpPointsOn(p.d.graph, p.d.transforms, p.rest.means.data(), n, got.data(), nullptr,
                              {resolveDevice(Device::Cuda)}),
                 DeviceMemoryError);
}
