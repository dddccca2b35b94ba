// CUDA Stage I update against the CPU applyStageOneCpu() (the reference) on the stripes sample
// bent by samples/specs/bend.json. Skips with a message where no GPU is present. Each test
// registers what it needs (CudaBackendsScope), so none depends on the order they run in.
//
// Tolerances are A-PRIORI, not yet measured (written on a machine without a GPU; confirm and
// tighten them on one). Both sides run the same double-precision code (deform/StageOneMath.h);
// nvcc contracts multiply-adds into FMAs and CUDA's exp/log/sqrt/cbrt are within 1-2 ulp of
// glibc's, so intermediate values differ by ~1e-15 relative. The outputs are stored as float:
// a value within 1e-15 of a float rounding boundary rounds the other way, so each output may
// differ by one float ulp (2^-23 relative). The polar step could in rare cases take Newton on one
// side and the Jacobi fallback on the other (convergence test at the boundary); both give the
// polar rotation to ~1e-12, still below one float ulp.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "BendSpec.h"
#include "CudaTestSupport.h"
#include "kernels/StageOneCuda.h"
#include "deform/StageOneDevice.h"
#include "demo/DemoModels.h"

using namespace splatwarp;

namespace {

constexpr double kUlpRel = 2.4e-7;      // two float ulps, relative (see top)
constexpr double kAbsFloor = 1e-6;      // absolute floor for values near 0 (float ulp at ~8)

double tolerance(double ref) { return std::max(kUlpRel * std::abs(ref), kAbsFloor); }

struct BendProblem {
    GaussianCloud rest = makeDemoModel("stripes");
    Deformation d;
    StageOneRig rig;
    BendProblem()
    {
        const DeformSpec spec = test::loadBendSpec();
        d = solveDeformation(rest, spec);
        rig = prepareStageOne(rest, d.graph);
    }
};

} // namespace

TEST(StageOneCuda, MatchesCpuOnStripesBend)
{
    SPLATWARP_REQUIRE_GPU();
    const BendProblem p;
    const StageOneResult cpu = applyStageOneCpu(p.rest, p.rig, p.d.graph, p.d.transforms, p.d.nodeMoving);
    auto engine = cuda::makeStageOneCuda(p.rest, p.rig, p.d.graph.nodeCount(), StageOneOptions{});
    const StageOneResult gpu = engine->apply(nodeAffines(p.d.graph, p.d.transforms), p.d.nodeMoving);
    ASSERT_EQ(gpu.moving, cpu.moving); // no arithmetic: weight > 0 on a moving node
    EXPECT_EQ(gpu.movingCount, cpu.movingCount);
    ASSERT_GT(cpu.movingCount, 0u);
    std::size_t bad = 0;
    auto check = [&](const std::vector<float>& a, const std::vector<float>& b, const char* what) {
        ASSERT_EQ(a.size(), b.size()) << what;
        for (std::size_t i = 0; i < a.size(); ++i)
            if (!(std::abs(double(a[i]) - b[i]) <= tolerance(b[i])) && bad++ < 10)
                ADD_FAILURE() << what << "[" << i << "]: GPU " << a[i] << " CPU " << b[i];
    };
    check(gpu.deformed.means, cpu.deformed.means, "means");
    check(gpu.deformed.logScales, cpu.deformed.logScales, "logScales");
    check(gpu.deformed.sh, cpu.deformed.sh, "sh");
    check(gpu.deformed.opacities, cpu.deformed.opacities, "opacities");
    // Rotations up to sign (matrixToQuat makes w >= 0, but w ~ 0 may flip with rounding).
    for (std::size_t i = 0; i < p.rest.size(); ++i) {
        double plus = 0, minus = 0;
        for (int c = 0; c < 4; ++c) {
            plus = std::max(plus, std::abs(double(gpu.deformed.rotations[4 * i + c]) - cpu.deformed.rotations[4 * i + c]));
            minus = std::max(minus, std::abs(double(gpu.deformed.rotations[4 * i + c]) + cpu.deformed.rotations[4 * i + c]));
        }
        if (!(std::min(plus, minus) <= kAbsFloor) && bad++ < 10) ADD_FAILURE() << "rotation " << i;
    }
    EXPECT_EQ(bad, 0u);
}

TEST(StageOneCuda, RepeatedUpdatesReuseTheResidentModel)
{
    SPLATWARP_REQUIRE_GPU();
    const test::CudaBackendsScope backends; // resolveDevice(Cuda) needs the probe, the updater the engine
    const BendProblem p;
    // Identity transforms after the bend: the engine must restart from the rest model each step.
    StageOneOptions options;
    options.device = resolveDevice(Device::Cuda);
    StageOneUpdater updater(p.rest, p.rig, p.d.graph, options);
    ASSERT_EQ(updater.device(), Device::Cuda);
    const StageOneResult bent = updater.apply(p.d.transforms, p.d.nodeMoving);
    EXPECT_EQ(bent.device, Device::Cuda);
    const StageOneResult still = updater.apply(NodeTransforms::identity(p.d.graph.nodeCount()), p.d.nodeMoving);
    // Identity affines skin every point to itself up to the float-weight sum (exact division), so
    // the means come back to float rounding of the rest values.
    for (std::size_t i = 0; i < p.rest.means.size(); ++i)
        ASSERT_NEAR(still.deformed.means[i], p.rest.means[i], tolerance(p.rest.means[i])) << i;
}
