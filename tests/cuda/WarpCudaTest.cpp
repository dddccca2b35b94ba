// CUDA point and sample warping against the CPU warpPoints()/warpSamples() (the reference).
// Skips with a message where no GPU is present.
//
// Tolerances are A-PRIORI, not yet measured (written on a machine without a GPU; confirm on one).
// The skin weights are the same (computed on the CPU for both). Skinning, the polar rotation,
// the SH rotation and F_k run the same double code (deform/WarpMath.h); nvcc's FMA contraction
// and CUDA's sqrt/cbrt change intermediates by ~1e-15 relative, so each float output may differ
// by one float rounding (2^-23 relative; two ulps allowed). F_k divides by the corner spread
// (Q Q^T)^-1, which amplifies a one-ulp difference of a warped corner position x by
// |x| / (cell size): kGradientAbs allows that for cells of >= 1/1000 of the model size.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "BendSpec.h"
#include "CudaTestSupport.h"
#include "vdb/SampleGrid.h"
#include "kernels/WarpCuda.h"
#include "deform/SampleWarp.h"
#include "demo/DemoModels.h"

using namespace splatwarp;

namespace {

constexpr double kUlpRel = 2.4e-7;     // two float ulps, relative
constexpr double kAbsFloor = 1e-6;     // values near 0 (features, rotation entries)
constexpr double kGradientAbs = 1e-3;  // F_k entries (dimensionless, ~1), see top

Deformation bend(const GaussianCloud& rest)
{
    const DeformSpec spec = test::loadBendSpec();
    return solveDeformation(rest, spec);
}

std::size_t countMismatches(const std::vector<float>& gpu, const std::vector<float>& cpu, double absFloor,
                            const char* what)
{
    EXPECT_EQ(gpu.size(), cpu.size()) << what;
    std::size_t bad = 0;
    for (std::size_t i = 0; i < std::min(gpu.size(), cpu.size()); ++i)
        if (!(std::abs(double(gpu[i]) - cpu[i]) <= std::max(kUlpRel * std::abs(cpu[i]), absFloor)) && bad++ < 10)
            ADD_FAILURE() << what << "[" << i << "]: GPU " << gpu[i] << " CPU " << cpu[i];
    return bad;
}

} // namespace

TEST(WarpCuda, PointsMatchCpu)
{
    SPLATWARP_REQUIRE_GPU();
    const GaussianCloud rest = makeDemoModel("stripes");
    const Deformation d = bend(rest);
    // Random points over the model's bounding box (held-out points are like these).
    Vec3f lo, hi;
    centreBounds(rest, lo, hi);
    std::mt19937 rng(3);
    const std::size_t count = 50000;
    std::vector<float> points(3 * count);
    for (std::size_t p = 0; p < count; ++p)
        for (int a = 0; a < 3; ++a) points[3 * p + a] = std::uniform_real_distribution<float>(lo[a], hi[a])(rng);
    std::vector<float> wc(3 * count), rc(9 * count), wg(3 * count), rg(9 * count);
    warpPoints(d.graph, d.transforms, points.data(), count, wc.data(), rc.data());
    cuda::warpPointsCuda(d.graph, d.transforms, points.data(), count, wg.data(), rg.data(), true);
    EXPECT_EQ(countMismatches(wg, wc, kAbsFloor, "warped"), 0u);
    EXPECT_EQ(countMismatches(rg, rc, kAbsFloor, "rotations"), 0u);
}

TEST(WarpCuda, SamplesMatchCpu)
{
    SPLATWARP_REQUIRE_GPU();
    const GaussianCloud rest = makeDemoModel("stripes", {3000, 5});
    const Deformation d = bend(rest);
    SampleGridOptions o;
    o.cells = 24;
    SampleGrid grid(rest, o);
    SampleSet cpu = grid.samples(), gpu = grid.samples();
    ASSERT_GT(cpu.shDegree, 0); // the SH rotation is exercised
    warpSamples(cpu, d);
    cuda::warpSamplesCuda(gpu, d.graph, d.transforms, true);
    EXPECT_EQ(countMismatches(gpu.warpedPositions, cpu.warpedPositions, kAbsFloor, "warpedPositions"), 0u);
    EXPECT_EQ(countMismatches(gpu.targetF, cpu.targetF, kAbsFloor, "targetF"), 0u);
    EXPECT_EQ(countMismatches(gpu.cellGradient, cpu.cellGradient, kGradientAbs, "cellGradient"), 0u);
    EXPECT_EQ(gpu.targetO, cpu.targetO);
}

TEST(WarpCuda, SkinWeightsMatchCpuExceptExactTies)
{
    SPLATWARP_REQUIRE_GPU();
    const GaussianCloud rest = makeDemoModel("stripes");
    const DeformationGraph graph = DeformationGraph::build(rest, GraphOptions{});
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> u(-2.5f, 2.5f);
    std::vector<float> points(3 * 100000);
    for (float& x : points) x = u(rng);
    const std::size_t count = points.size() / 3;
    const SkinWeights cpu = graph.skinWeights(points.data(), count);
    const SkinWeights gpu = cuda::skinWeightsCuda(graph, points.data(), count);
    ASSERT_EQ(gpu.k, cpu.k);
    ASSERT_EQ(gpu.nodes.size(), cpu.nodes.size());
    // Random points have no exact ties, so the node sets agree; an FMA in the GPU's squared
    // distance could reorder two nodes within ~1e-16 relative of each other (then the sets still
    // agree) and moves each weight by ~1e-16 relative, below float rounding except at a boundary:
    // one float ulp allowed.
    const std::size_t k = std::size_t(cpu.k);
    std::size_t bad = 0;
    for (std::size_t p = 0; p < count; ++p) {
        std::vector<std::int32_t> a(gpu.nodes.begin() + p * k, gpu.nodes.begin() + (p + 1) * k),
            b(cpu.nodes.begin() + p * k, cpu.nodes.begin() + (p + 1) * k);
        std::sort(a.begin(), a.end());
        std::sort(b.begin(), b.end());
        if (a != b && bad++ < 10) ADD_FAILURE() << "point " << p << ": node sets differ";
    }
    EXPECT_EQ(countMismatches(gpu.weights, cpu.weights, 1e-7, "weights"), 0u);
    EXPECT_EQ(bad, 0u);
}
