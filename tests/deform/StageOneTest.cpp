#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>

#include <Eigen/Dense>

#include "deform/StageOne.h"
#include "deform/StageOneDevice.h"
#include "demo/DemoModels.h"
#include "sh/SphericalHarmonics.h"

using namespace splatwarp;

namespace {

// Worst relative error measured for the rigid test: 5.9e-8 (float storage of the outputs).
constexpr double kRigidTolerance = 1e-5;

double relErr(double a, double b) { return std::abs(a - b) / std::max(1.0, std::max(std::abs(a), std::abs(b))); }

DeformSpec bendSpec()
{
    DeformSpec s = loadDeformSpec(std::string(SPLATWARP_SOURCE_DIR) + "/samples/specs/bend.json");
    s.graph.nodes = 64;
    return s;
}

/// Stage I of a solved deformation as the deform job runs it: the rig, then one update.
StageOneResult runStageOne(const GaussianCloud& rest, const Deformation& d, const StageOneOptions& o = {})
{
    const StageOneRig rig = prepareStageOne(rest, d.graph, o);
    return StageOneUpdater(rest, rig, d.graph, o).apply(d.transforms, d.nodeMoving);
}

void expectFinite(const GaussianCloud& g)
{
    for (float v : g.means) ASSERT_TRUE(std::isfinite(v));
    for (float v : g.rotations) ASSERT_TRUE(std::isfinite(v));
    for (float v : g.logScales) ASSERT_TRUE(std::isfinite(v));
    for (float v : g.sh) ASSERT_TRUE(std::isfinite(v));
}

} // namespace

TEST(StageOne, RigidMotionOfAllNodesMovesGaussiansRigidly)
{
    const GaussianCloud rest = makeDemoModel("stripes", DemoModelOptions{2000, 4});
    const DeformationGraph graph = DeformationGraph::build(rest, GraphOptions{48, 8, 0});
    const Mat3d r = quatToMatrix(Quatd{0.7, -0.2, 0.5, 0.4});
    const Vec3d tr(0.5, -2.0, 1.25);
    NodeTransforms x = NodeTransforms::identity(graph.nodeCount());
    for (std::size_t j = 0; j < graph.nodeCount(); ++j) {
        x.A[j] = r;
        x.t[j] = r * graph.nodes()[j] + tr - graph.nodes()[j];
    }
    const StageOneRig rig = prepareStageOne(rest, graph);
    const StageOneResult res = applyStageOneCpu(rest, rig, graph, x, std::vector<std::uint8_t>(graph.nodeCount(), 1));
    EXPECT_EQ(res.movingCount, rest.size());

    // Reference: rotate the model directly.
    GaussianCloud ref = rest;
    rotateCloudSh(ref, r);
    double worst = 0.0;
    for (std::size_t i = 0; i < rest.size(); ++i) {
        const Vec3d m = r * Vec3d(rest.mean(i)) + tr;
        const Quatf q0 = rest.rotation(i), q1 = res.deformed.rotation(i);
        const Mat3d r0 = r * quatToMatrix(Quatd{q0.w, q0.x, q0.y, q0.z});
        const Mat3d r1 = quatToMatrix(Quatd{q1.w, q1.x, q1.y, q1.z});
        for (int a = 0; a < 3; ++a) {
            worst = std::max(worst, relErr(res.deformed.means[3 * i + a], m[a]));
            worst = std::max(worst, relErr(res.deformed.logScales[3 * i + a], rest.logScales[3 * i + a]));
            for (int b = 0; b < 3; ++b) worst = std::max(worst, relErr(r1[a][b], r0[a][b]));
        }
        for (int c = 0; c < rest.shStride(); ++c) worst = std::max(worst, relErr(res.deformed.shOf(i)[c], ref.shOf(i)[c]));
    }
    EXPECT_LT(worst, kRigidTolerance);
}

TEST(StageOne, BendKeepsStaticGaussiansBitExactAndSerialEqualsParallel)
{
    const GaussianCloud rest = makeDemoModel("stripes", DemoModelOptions{3000, 5});
    DeformSpec spec = bendSpec();
    spec.handles[0].boxMax.x = 0.4; // a fixed slab wide enough to hold Gaussians that see only fixed nodes
    const Deformation d = solveDeformation(rest, spec);
    StageOneOptions serial;
    serial.threaded = false;
    const StageOneResult a = runStageOne(rest, d);
    const StageOneResult b = runStageOne(rest, d, serial);
    EXPECT_GT(a.movingCount, 0u);
    EXPECT_LT(a.movingCount, rest.size()); // the fixed end does not move
    EXPECT_EQ(a.moving, b.moving);
    EXPECT_EQ(a.deformed.means, b.deformed.means);
    EXPECT_EQ(a.deformed.rotations, b.deformed.rotations);
    EXPECT_EQ(a.deformed.logScales, b.deformed.logScales);
    EXPECT_EQ(a.deformed.sh, b.deformed.sh);
    for (std::size_t i = 0; i < rest.size(); ++i) {
        if (a.moving[i]) continue;
        EXPECT_EQ(std::memcmp(&a.deformed.means[3 * i], &rest.means[3 * i], 12), 0);
        EXPECT_EQ(std::memcmp(&a.deformed.rotations[4 * i], &rest.rotations[4 * i], 16), 0);
        EXPECT_EQ(std::memcmp(&a.deformed.logScales[3 * i], &rest.logScales[3 * i], 12), 0);
        EXPECT_EQ(std::memcmp(a.deformed.shOf(i), rest.shOf(i), sizeof(float) * std::size_t(rest.shStride())), 0);
    }
    expectFinite(a.deformed);
    // The rotated end turned by ~90 degrees about z: Gaussians at the far end now run along y.
    std::size_t checked = 0;
    for (std::size_t i = 0; i < rest.size(); ++i) {
        if (rest.mean(i).x < 1.9f) continue;
        const Vec3f p = a.deformed.mean(i);
        EXPECT_LT(std::abs(p.x - 0.55f), 0.6f);
        EXPECT_GT(p.y, 1.6f);
        ++checked;
    }
    EXPECT_GT(checked, 0u);
}

TEST(StageOne, FlatAndNearZeroScaleGaussiansStayFinite)
{
    GaussianCloud rest = makeDemoModel("stripes", DemoModelOptions{1500, 6});
    for (std::size_t i = 0; i < rest.size(); i += 3) rest.logScales[3 * i + 2] = -40.0f;          // flat
    for (std::size_t i = 1; i < rest.size(); i += 7)
        for (int a = 0; a < 3; ++a) rest.logScales[3 * i + a] = -80.0f;                            // a point
    for (std::size_t i = 2; i < rest.size(); i += 11) rest.setRotation(i, Quatf{0, 0, 0, 0});       // zero quaternion
    const Deformation d = solveDeformation(rest, bendSpec());
    const StageOneResult res = runStageOne(rest, d);
    EXPECT_GT(res.movingCount, 0u);
    expectFinite(res.deformed);
    // Flat Gaussians stay flat: the thin axis keeps roughly its log-scale.
    for (std::size_t i = 0; i < rest.size(); i += 3)
        if (res.moving[i]) EXPECT_LT(res.deformed.logScales[3 * i + 2], -30.0f);
}

// A smooth non-rigid field (per-node rotation times a mild symmetric stretch) against a naive
// double reference: skinPoint() per endpoint and the polar factors from Eigen's SVD. Worst
// relative error measured: 7.9e-8 (float storage), checked against kRigidTolerance.
TEST(StageOne, NonRigidFieldMatchesNaiveSvdReference)
{
    const GaussianCloud rest = makeDemoModel("stripes", DemoModelOptions{2000, 5});
    const DeformationGraph graph = DeformationGraph::build(rest, GraphOptions{48, 8, 0});
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    NodeTransforms x = NodeTransforms::identity(graph.nodeCount());
    for (std::size_t j = 0; j < graph.nodeCount(); ++j) {
        const Mat3d r = quatToMatrix(Quatd{1.0, 0.3 * u(rng), 0.3 * u(rng), 0.3 * u(rng)});
        Mat3d s = Mat3d::identity();
        for (int a = 0; a < 3; ++a)
            for (int b = a; b < 3; ++b) s[a][b] = s[b][a] = s[a][b] + 0.2 * u(rng);
        x.A[j] = r * s;
        x.t[j] = Vec3d(0.1 * u(rng), 0.1 * u(rng), 0.1 * u(rng));
    }
    const StageOneRig rig = prepareStageOne(rest, graph);
    StageOneOptions o; // the polar shape against the SVD's polar factors
    o.shape = StageOneShape::Polar;
    const StageOneResult res =
        applyStageOneCpu(rest, rig, graph, x, std::vector<std::uint8_t>(graph.nodeCount(), 1), o);
    ASSERT_EQ(res.movingCount, rest.size());
    double worst = 0.0;
    for (std::size_t i = 0; i < rest.size(); ++i) {
        const Quatf qf = rest.rotation(i);
        const Mat3d r0 = quatToMatrix(Quatd{qf.w, qf.x, qf.y, qf.z});
        double s[3], smax = 0.0;
        for (int a = 0; a < 3; ++a) smax = std::max(smax, s[a] = std::exp(double(rest.logScales[3 * i + a])));
        const double eps = std::max(o.flatEpsilon * smax, o.absoluteEpsilon * rig.extent);
        const Vec3d c(rest.mean(i));
        Eigen::Matrix3d m = Eigen::Matrix3d::Zero();
        for (int a = 0; a < 3; ++a) {
            const Vec3d axis(r0[0][a], r0[1][a], r0[2][a]);
            const double h = o.endpointSigmas * (s[a] + eps);
            const Vec3d d = skinPoint(graph, x, rig.weights, 7 * i + 1 + 2 * a, c + axis * h) -
                            skinPoint(graph, x, rig.weights, 7 * i + 2 + 2 * a, c - axis * h);
            m += Eigen::Vector3d(d.x, d.y, d.z) * Eigen::Vector3d(axis.x, axis.y, axis.z).transpose() / (2.0 * h);
        }
        const Eigen::JacobiSVD<Eigen::Matrix3d> svd(m, Eigen::ComputeFullU | Eigen::ComputeFullV);
        ASSERT_GT(m.determinant(), 0.0) << "the field must keep orientation for this reference";
        const Eigen::Matrix3d rot = svd.matrixU() * svd.matrixV().transpose();
        const Eigen::Matrix3d str = svd.matrixV() * svd.singularValues().asDiagonal() * svd.matrixV().transpose();
        const Vec3d centre = skinPoint(graph, x, rig.weights, 7 * i, c);
        const Quatf q1 = res.deformed.rotation(i);
        const Mat3d r1 = quatToMatrix(Quatd{q1.w, q1.x, q1.y, q1.z});
        for (int a = 0; a < 3; ++a) {
            worst = std::max(worst, relErr(res.deformed.means[3 * i + a], centre[a]));
            const Eigen::Vector3d ra(r0[0][a], r0[1][a], r0[2][a]);
            const double logScale = double(rest.logScales[3 * i + a]) + std::log(ra.dot(str * ra));
            worst = std::max(worst, relErr(res.deformed.logScales[3 * i + a], logScale));
            for (int b = 0; b < 3; ++b) {
                double expected = 0.0;
                for (int k = 0; k < 3; ++k) expected += rot(a, k) * r0[k][b];
                worst = std::max(worst, relErr(r1[a][b], expected));
            }
        }
    }
    EXPECT_LT(worst, kRigidTolerance);
}
