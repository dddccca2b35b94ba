#include <gtest/gtest.h>

#include <cmath>

#include "vdb/SampleGrid.h"
#include "deform/SampleWarp.h"
#include "core/Polar.h"
#include "deform/DeformSpec.h"
#include "demo/DemoModels.h"
#include "sh/SphericalHarmonics.h"

using namespace splatwarp;

namespace {

Mat3d rotationAbout(Vec3d axis, double angle)
{
    axis = axis / length(axis);
    const double s = std::sin(angle / 2);
    return quatToMatrix(Quatd{std::cos(angle / 2), axis.x * s, axis.y * s, axis.z * s});
}

/// Node transforms that move every node (and hence every skinned point) by x -> M x + T.
NodeTransforms affineTransforms(const DeformationGraph& graph, const Mat3d& m, const Vec3d& t)
{
    NodeTransforms nt = NodeTransforms::identity(graph.nodeCount());
    for (std::size_t j = 0; j < graph.nodeCount(); ++j) {
        const Vec3d g = graph.nodes()[j];
        nt.A[j] = m;
        nt.t[j] = m * g + t - g;
    }
    return nt;
}

SampleGrid smallGrid(float fineBelow = 0.0f)
{
    SampleGridOptions o;
    o.cells = 12;
    o.fineBelow = fineBelow;
    return SampleGrid(makeDemoModel("stripes", {1200, 9}), o);
}

/// Worst deviations of a warped sample set from the rigid motion x -> r x + t of its rest set
/// (targetO must be unchanged exactly).
struct RigidErrors {
    double position = 0, features = 0, gradient = 0;
};
RigidErrors rigidErrors(const SampleSet& rest, const SampleSet& set, const Mat3d& r, const Vec3d& t)
{
    RigidErrors e;
    const std::size_t stride = std::size_t(set.featureStride());
    const ShRotation shr(r);
    std::vector<float> expected(stride);
    for (std::size_t s = 0; s < set.sampleCount(); ++s) {
        const Vec3d q = r * Vec3d(rest.restPositions[3 * s], rest.restPositions[3 * s + 1], rest.restPositions[3 * s + 2]) + t;
        for (int k = 0; k < 3; ++k) e.position = std::max(e.position, std::fabs(set.warpedPositions[3 * s + k] - q[k]));
        std::copy(&rest.targetF[s * stride], &rest.targetF[s * stride] + stride, expected.begin());
        shr.apply(set.shDegree, expected.data());
        for (std::size_t k = 0; k < stride; ++k)
            e.features = std::max(e.features, double(std::fabs(set.targetF[s * stride + k] - expected[k])));
        EXPECT_EQ(set.targetO[s], rest.targetO[s]);
    }
    for (std::size_t c = 0; c < set.cellCount(); ++c)
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) e.gradient = std::max(e.gradient, std::fabs(set.cellGradient[9 * c + 3 * i + j] - r.m[i][j]));
    return e;
}

} // namespace

TEST(SampleWarp, RigidMotionWarpsExactlyAndRotatesTargets)
{
    SampleGrid grid = smallGrid();
    const SampleSet rest = grid.samples();
    const DeformationGraph graph = DeformationGraph::build(makeDemoModel("stripes", {1200, 9}), GraphOptions{32, 8, 0});
    const Mat3d r = rotationAbout(Vec3d(0.3, -1.0, 0.5), 1.1);
    const Vec3d t(0.4, -2.0, 1.5);
    SampleSet& set = grid.samples();
    warpSamples(set, graph, affineTransforms(graph, r, t));

    const RigidErrors e = rigidErrors(rest, set, r, t);
    // Measured: positions 2.4e-7 (float rounding of ~2-unit coordinates), features 0 (the polar
    // rotation of sum_j w_j R equals R to ~1e-16, below float resolution).
    EXPECT_LT(e.position, 1e-6);
    EXPECT_LT(e.features, 1e-5);
    // Measured 5.1e-7 (float corner positions).
    EXPECT_LT(e.gradient, 5e-6);
    EXPECT_EQ(set.restPositions, rest.restPositions);
    EXPECT_EQ(set.cellSkip, rest.cellSkip);
}

TEST(SampleWarp, AffineMotionGivesThatGradientAndItsPolarRotation)
{
    SampleGrid grid = smallGrid();
    const SampleSet rest = grid.samples();
    const DeformationGraph graph = DeformationGraph::build(makeDemoModel("stripes", {1200, 9}), GraphOptions{16, 6, 0});
    Mat3d m = rotationAbout(Vec3d(1, 1, 0), 0.7);
    m.m[0][1] += 0.4; // shear
    m.m[2][2] *= 1.5; // stretch
    warpSamples(grid.samples(), graph, affineTransforms(graph, m, Vec3d(0, 0, 0)));
    const SampleSet& set = grid.samples();
    for (std::size_t c = 0; c < set.cellCount(); ++c)
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) ASSERT_NEAR(set.cellGradient[9 * c + 3 * i + j], m.m[i][j], 2e-4);
    // SH rotated by the rotation of the polar decomposition of M (computed here from M^T M).
    const Mat3d rot = polarRotation(m);
    const Mat3d rtr = rot.transposed() * rot;
    EXPECT_NEAR(rot.determinant(), 1.0, 1e-12);
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) EXPECT_NEAR(rtr.m[i][j], i == j ? 1.0 : 0.0, 1e-12);
    const Mat3d s = rot.transposed() * m; // must be symmetric positive definite
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) EXPECT_NEAR(s.m[i][j], s.m[j][i], 1e-12);
    EXPECT_GT(s.determinant(), 0.0);
    const std::size_t stride = std::size_t(set.featureStride());
    const ShRotation shr(rot);
    for (std::size_t q = 0; q < set.sampleCount(); q += 97) {
        std::vector<float> expected(&rest.targetF[q * stride], &rest.targetF[q * stride] + stride);
        shr.apply(set.shDegree, expected.data());
        for (std::size_t k = 0; k < stride; ++k) ASSERT_NEAR(set.targetF[q * stride + k], expected[k], 1e-5);
    }
}

// Fine cells (8^3 samples, octant by octant) and coarse ones side by side: each cell's F_k from
// its own corner samples is the affine motion's matrix.
TEST(SampleWarp, AffineMotionGradientInFineAndCoarseCells)
{
    SampleGrid grid = smallGrid(100.0f); // every cell holding a Gaussian's centre is fine
    ASSERT_GT(grid.stats().fineCells, 0u);
    ASSERT_LT(grid.stats().fineCells, grid.stats().cells);
    const DeformationGraph graph = DeformationGraph::build(makeDemoModel("stripes", {1200, 9}), GraphOptions{16, 6, 0});
    Mat3d m = rotationAbout(Vec3d(0, 1, 1), 0.5);
    m.m[1][2] += 0.3;
    m.m[0][0] *= 0.7;
    const Vec3d t(0.1, -0.2, 0.05);
    warpSamples(grid.samples(), graph, affineTransforms(graph, m, t));
    const SampleSet& set = grid.samples();
    for (std::size_t c = 0; c < set.cellCount(); ++c)
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) ASSERT_NEAR(set.cellGradient[9 * c + 3 * i + j], m.m[i][j], 2e-4) << "cell " << c;
    for (std::size_t s = 0; s < set.sampleCount(); s += 13) {
        const Vec3d q = m * Vec3d(set.restPositions[3 * s], set.restPositions[3 * s + 1], set.restPositions[3 * s + 2]) + t;
        for (int k = 0; k < 3; ++k) ASSERT_NEAR(set.warpedPositions[3 * s + k], q[k], 1e-4);
    }
}

TEST(SampleWarp, PolarRotationIsProperForReflections)
{
    Mat3d m = rotationAbout(Vec3d(0.2, 0.5, 1), 2.0);
    for (int j = 0; j < 3; ++j) m.m[j][0] *= -0.5; // det < 0
    const Mat3d r = polarRotation(m);
    EXPECT_NEAR(r.determinant(), 1.0, 1e-12);
}

TEST(SampleWarp, RigidSpecWarpsRigidly)
{
    const GaussianCloud cloud = makeDemoModel("stripes", {1500, 3});
    SampleGridOptions o;
    o.cells = 12;
    SampleGrid grid(cloud, o);
    const SampleSet rest = grid.samples();
    const DeformSpec spec = loadDeformSpec(std::string(SPLATWARP_SOURCE_DIR) + "/samples/specs/rigid.json");
    ASSERT_EQ(spec.handles.size(), 1u);
    const Deformation d = solveDeformation(cloud, spec);
    // The spec's rotation, and the translation it implies (taken from node 0's solved motion).
    const Mat3d r = rotationAbout(spec.handles[0].axis, spec.handles[0].degrees * 3.14159265358979323846 / 180.0);
    const Vec3d g0 = d.graph.nodes()[0], t = g0 + d.transforms.t[0] - r * g0;
    warpSamples(grid.samples(), d);
    const RigidErrors e = rigidErrors(rest, grid.samples(), r, t);
    // Measured: positions 1.1e-6, features 6e-8, gradients 1.5e-6 (the ED solve's convergence
    // plus float rounding).
    EXPECT_LT(e.position, 1e-5);
    EXPECT_LT(e.features, 1e-5);
    EXPECT_LT(e.gradient, 1e-5);
}
