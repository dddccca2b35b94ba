// evaluateHeldOut() on a device, in a build without registered CUDA: the held-out options' device
// reaches the points, Cpu and Auto give the same report (the CPU path), Cuda is refused with
// InputError when resolved, before any work.
#include <gtest/gtest.h>

#include <string>

#include "job/HeldOutEval.h"
#include "deform/DeformSpec.h"
#include "demo/DemoModels.h"

using namespace splatwarp;

TEST(HeldOutDevice, CpuAndAutoAgreeAndCudaIsRefusedWithoutCuda)
{
    const GaussianCloud rest = makeDemoModel("stripes");
    SampleGridOptions go;
    go.cells = 10;
    const SampleGrid grid(rest, go);
    const Deformation deformation =
        solveDeformation(rest, loadDeformSpec(std::string(SPLATWARP_SOURCE_DIR) + "/samples/specs/bend.json"));
    HeldOutOptions ho;
    ho.points = 3000;
    HeldOutPoints points = makeHeldOutPoints(grid, deformation, ho);
    EXPECT_EQ(points.features.device.requested(), Device::Cpu);
    // The rest model against itself pushed through a bend: a nonzero error to compare.
    const FieldErrorReport cpu = evaluateHeldOut(rest, rest, points);
    ho.device = resolveDevice(Device::Auto);
    points = makeHeldOutPoints(grid, deformation, ho);
    EXPECT_EQ(points.features.device.requested(), Device::Auto);
    const FieldErrorReport autoRun = evaluateHeldOut(rest, rest, points);
    EXPECT_GT(cpu.opacity, 0.0);
    EXPECT_EQ(autoRun.opacity, cpu.opacity);
    EXPECT_EQ(autoRun.color, cpu.color);
    EXPECT_EQ(autoRun.insidePoints, cpu.insidePoints);
    EXPECT_THROW(resolveDevice(Device::Cuda), InputError);
}
