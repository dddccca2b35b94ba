// Rasteriser dispatch in a CPU-only process (this binary never links the CUDA kernels): CUDA
// requested without support fails clearly, auto renders on the CPU, a registered GPU rasteriser
// is used under auto/cuda, and running out of GPU memory falls back to the CPU under auto only.
// The CLI tests hide any GPU (CUDA_VISIBLE_DEVICES=-1), so they hold in CUDA builds too.
#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>

#include "core/Device.h"
#include "image/ImageIO.h"
#include "io/GaussianIO.h"
#include "render/ComparisonSheet.h"
#include "render/RenderDevice.h"
#include "render/RenderTestUtil.h"
#include "support/TestSupport.h"

using namespace splatwarp;
using namespace splatwarp::test;

namespace {

/// Registers fakes for one test and always restores the CPU-only state.
struct FakeCuda {
    FakeCuda(bool (*probe)(), RenderFunction render)
    {
        registerCudaProbe(probe);
        registerRenderCuda(render);
    }
    ~FakeCuda()
    {
        registerCudaProbe(nullptr);
        registerRenderCuda(nullptr);
    }
};

bool gpu() { return true; }

int gFakeCalls = 0;
Image fakeRender(const GaussianCloud&, const Camera& camera, const RenderOptions&)
{
    ++gFakeCalls;
    return Image(camera.width, camera.height, 4, 0.25f); // no real render is uniformly 0.25 with alpha 0.25
}
Image fakeOutOfMemory(const GaussianCloud&, const Camera&, const RenderOptions&)
{
    ++gFakeCalls;
    throw DeviceMemoryError("CUDA: cannot allocate 1234 bytes of GPU memory for tile sort keys");
}

/// Render options on a device resolved now (after any fake registration).
RenderOptions on(Device requested)
{
    RenderOptions o;
    o.device = resolveDevice(requested);
    return o;
}

struct Scene {
    GaussianCloud cloud = smallSample("stripes", 1500);
    Camera camera = smallOrbit(cloud, 1, 40, 28)[0];
    Image cpu = renderGaussians(cloud, camera);
};

} // namespace

TEST(RenderDevice, CpuOnlyBuildRendersAutoOnTheCpuAndRejectsCuda)
{
    const Scene s;
    Device used = Device::Cuda;
    EXPECT_EQ(renderGaussiansOn(s.cloud, s.camera, on(Device::Auto), &used).pixels, s.cpu.pixels);
    EXPECT_EQ(used, Device::Cpu);
    used = Device::Cuda;
    EXPECT_EQ(renderGaussiansOn(s.cloud, s.camera, on(Device::Cpu), &used).pixels, s.cpu.pixels);
    EXPECT_EQ(used, Device::Cpu);
    const std::string e = test::inputErrorMessage([&] { on(Device::Cuda); });
    EXPECT_NE(e.find("--device cuda"), std::string::npos) << e;
    EXPECT_NE(e.find("no CUDA support"), std::string::npos) << e;
}

TEST(RenderDevice, RegisteredGpuRasteriserIsUsedUnderAutoAndCuda)
{
    const Scene s;
    const FakeCuda fake(&gpu, &fakeRender);
    gFakeCalls = 0;
    for (Device d : {Device::Auto, Device::Cuda}) {
        Device used = Device::Cpu;
        const Image img = renderGaussiansOn(s.cloud, s.camera, on(d), &used);
        EXPECT_EQ(used, Device::Cuda) << deviceName(d);
        EXPECT_EQ(img.at(3, 4, 3), 0.25f) << deviceName(d);
    }
    EXPECT_EQ(gFakeCalls, 2);
    EXPECT_EQ(renderGaussiansOn(s.cloud, s.camera, on(Device::Cpu)).pixels, s.cpu.pixels);
    EXPECT_EQ(gFakeCalls, 2);
}

TEST(RenderDevice, GpuWithoutRasteriserFallsBackUnderAutoOnly)
{
    const Scene s;
    const FakeCuda fake(&gpu, nullptr); // a probe but no rasteriser: CUDA build without this kernel
    EXPECT_EQ(renderGaussiansOn(s.cloud, s.camera, on(Device::Auto)).pixels, s.cpu.pixels);
    const std::string e = test::inputErrorMessage([&] { renderGaussiansOn(s.cloud, s.camera, on(Device::Cuda)); });
    EXPECT_NE(e.find("no CUDA rasteriser"), std::string::npos) << e;
}

TEST(RenderDevice, OutOfGpuMemoryFallsBackUnderAutoAndPropagatesUnderCuda)
{
    const Scene s;
    const FakeCuda fake(&gpu, &fakeOutOfMemory);
    gFakeCalls = 0;
    Device used = Device::Cuda;
    EXPECT_EQ(renderGaussiansOn(s.cloud, s.camera, on(Device::Auto), &used).pixels, s.cpu.pixels);
    EXPECT_EQ(used, Device::Cpu);
    EXPECT_EQ(gFakeCalls, 1);
    try {
        renderGaussiansOn(s.cloud, s.camera, on(Device::Cuda));
        ADD_FAILURE() << "expected DeviceMemoryError";
    } catch (const DeviceMemoryError& e) {
        EXPECT_NE(std::string(e.what()).find("tile sort keys"), std::string::npos) << e.what();
    }
    EXPECT_EQ(gFakeCalls, 2);
}

TEST(RenderDevice, ComparisonSheetRendersOnItsDevice)
{
    const Scene s;
    ComparisonSheetOptions o;
    const FakeCuda fake(&gpu, &fakeRender);
    o.render = on(Device::Cuda);
    gFakeCalls = 0;
    renderComparisonSheet({&s.cloud, &s.cloud}, {"a", "b"}, {s.camera, s.camera, s.camera}, o);
    EXPECT_EQ(gFakeCalls, 6); // every cell
    o.render = on(Device::Cpu);
    renderComparisonSheet({&s.cloud}, {"a"}, {s.camera}, o);
    EXPECT_EQ(gFakeCalls, 6);
}

namespace {

/// Hides every CUDA device from the CLI processes this test starts (an invalid index ends the list).
class HiddenGpu {
public:
    HiddenGpu()
    {
        const char* old = std::getenv("CUDA_VISIBLE_DEVICES");
        mHad = old != nullptr;
        if (mHad) mOld = old;
        setenv("CUDA_VISIBLE_DEVICES", "-1", 1);
    }
    ~HiddenGpu()
    {
        if (mHad) setenv("CUDA_VISIBLE_DEVICES", mOld.c_str(), 1);
        else unsetenv("CUDA_VISIBLE_DEVICES");
    }

private:
    bool mHad = false;
    std::string mOld;
};

std::string slurp(const std::string& path)
{
    std::ifstream in(path);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
}

} // namespace

TEST(RenderDeviceCli, CudaWithoutGpuIsBadInputAndAutoRendersOnTheCpu)
{
    const HiddenGpu hidden;
    const TempDir dir;
    const std::string model = dir.file("bar.ply");
    writePly(model, smallSample("stripes", 1500));
    const std::string log = dir.file("log.txt");

    EXPECT_EQ(runCli("render " + model + " -o " + dir.file("cuda.exr") + " --size 24x20 --device cuda", log), 1);
    EXPECT_NE(slurp(log).find("--device cuda"), std::string::npos) << slurp(log);
    EXPECT_FALSE(std::filesystem::exists(dir.file("cuda.exr")));

    ASSERT_EQ(runCli("render " + model + " -o " + dir.file("auto.exr") + " --size 24x20 --device auto", log), 0);
    EXPECT_NE(slurp(log).find(" on cpu "), std::string::npos) << slurp(log);
    ASSERT_EQ(runCli("-q render " + model + " -o " + dir.file("cpu.exr") + " --size 24x20 --device cpu"), 0);
    EXPECT_EQ(readExr(dir.file("auto.exr")).pixels, readExr(dir.file("cpu.exr")).pixels);

    EXPECT_EQ(runCli("-q render " + model + " -o " + dir.file("x.exr") + " --device gpu"), 2); // usage error

    EXPECT_EQ(runCli("-q bench render " + model + " --size 16x16 --repeats 1 --device cuda", log), 1);
    EXPECT_NE(slurp(log).find("--device cuda"), std::string::npos) << slurp(log);
    ASSERT_EQ(runCli("-q bench render " + model + " --size 16x16 --repeats 1 --device auto", log), 0);
    EXPECT_NE(slurp(log).find("cpu, "), std::string::npos) << slurp(log);
}
