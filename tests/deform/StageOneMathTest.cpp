// The Stage I per-Gaussian update (deform/StageOneMath.h, GPU layout, also run by the CUDA
// kernel) against the plain reference path: skinPoint() per endpoint, the least-squares M
// with its 3x3 inverse, the Jacobi polar decomposition and ShRotation, all in double.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>

#include "core/Polar.h"
#include "deform/StageOne.h"
#include "deform/StageOneMath.h"
#include "demo/DemoModels.h"
#include "sh/ShRotationMath.h"

using namespace splatwarp;

namespace {

// The update and the reference agree to ~1e-12 relative in double (different but exact-in-the-limit
// formulas: Newton vs Jacobi polar, M without vs with the inverse); both are stored as float, so
// the outputs may differ by one float rounding: 2^-24 relative, i.e. ~6e-8. 1e-6 leaves room for
// the log of the stretch and the SH sums (|coefficients| <= ~3 in the sample).
constexpr double kFloatTolerance = 1e-6;

// The affine covariance is rebuilt from float rotation and log-scales: ~3 float roundings of its
// largest entry.
constexpr double kAffineTolerance = 1e-6;

double relErr(double a, double b) { return std::abs(a - b) / std::max(1.0, std::max(std::abs(a), std::abs(b))); }

/// Covariance R diag(exp(2 logScale)) R^T of Gaussian i of a cloud.
Mat3d covarianceOf(const GaussianCloud& g, std::size_t i)
{
    const Quatf q = g.rotation(i);
    const Mat3d r = quatToMatrix(Quatd{q.w, q.x, q.y, q.z});
    Mat3d d = Mat3d::identity();
    for (int a = 0; a < 3; ++a) d[a][a] = std::exp(2.0 * double(g.logScales[3 * i + std::size_t(a)]));
    return r * d * r.transposed();
}

/// The update of every moving Gaussian of a bent stripes model against a plain double reference:
/// M = (P Q^T)(Q Q^T)^-1 over the 6 endpoint offsets, polar M = R S; polar shape: rotation R R0 and
/// log-scales + log stretch; affine shape: covariance M Sigma M^T (relative to its largest entry).
void checkAgainstReferenceOnBend(StageOneShape shape, double endpointSigmas = 2.0)
{
    const GaussianCloud rest = makeDemoModel("stripes", DemoModelOptions{3000, 3});
    DeformSpec spec = loadDeformSpec(std::string(SPLATWARP_SOURCE_DIR) + "/samples/specs/bend.json");
    spec.graph.nodes = 64;
    const Deformation d = solveDeformation(rest, spec);
    StageOneOptions o;
    o.shape = shape;
    o.endpointSigmas = endpointSigmas;
    const StageOneRig rig = prepareStageOne(rest, d.graph, o);
    const StageOneResult res = applyStageOneCpu(rest, rig, d.graph, d.transforms, d.nodeMoving, o);
    ASSERT_GT(res.movingCount, 0u);

    const StageOneParams p = stageOneParams(o, rig.extent);
    double worst = 0.0;
    for (std::size_t i = 0; i < rest.size(); ++i) {
        bool moving = false;
        const std::size_t k = std::size_t(rig.weights.k);
        for (std::size_t q = i * 7 * k; q < (i + 1) * 7 * k; ++q)
            moving = moving || (rig.weights.weights[q] > 0.0f && d.nodeMoving[std::size_t(rig.weights.nodes[q])]);
        ASSERT_EQ(res.moving[i], moving ? 1 : 0) << i;
        if (!moving) {
            // Static Gaussians are bit-exact copies.
            for (int a = 0; a < 3; ++a) ASSERT_EQ(res.deformed.means[3 * i + a], rest.means[3 * i + a]);
            continue;
        }
        const StageOneRestFrame f = stageOneRestFrame(rest.means.data(), rest.rotations.data(), rest.logScales.data(), i, p);
        // Reference: M = (P Q^T)(Q Q^T)^-1 over the 6 endpoint offsets, polar M = R S.
        const Vec3d c = skinPoint(d.graph, d.transforms, rig.weights, 7 * i, f.centre);
        Mat3d pq, qq;
        for (int e = 0; e < 6; ++e) {
            const Vec3d x = stageOneEndpoint(f, e, o.endpointSigmas);
            const Vec3d pe = skinPoint(d.graph, d.transforms, rig.weights, 7 * i + 1 + std::size_t(e), x) - c;
            const Vec3d qe = x - f.centre;
            for (int r = 0; r < 3; ++r)
                for (int s = 0; s < 3; ++s) {
                    pq.m[r][s] += pe[r] * qe[s];
                    qq.m[r][s] += qe[r] * qe[s];
                }
        }
        Mat3d rot, stretchMat;
        polarDecomposition(pq * qq.inverse(), rot, stretchMat);
        const Mat3d rr0 = rot * f.r0;
        for (int a = 0; a < 3; ++a) worst = std::max(worst, relErr(res.deformed.means[3 * i + a], c[a]));
        std::vector<double> sh(rest.shOf(i), rest.shOf(i) + rest.shStride());
        ShRotation(rot, rest.shDegree).apply(rest.shDegree, sh.data());
        for (int s = 0; s < rest.shStride(); ++s) worst = std::max(worst, relErr(res.deformed.shOf(i)[s], sh[s]));
        if (shape == StageOneShape::Affine) {
            const Mat3d m = pq * qq.inverse();
            const Mat3d ref = m * covarianceOf(rest, i) * m.transposed(), got = covarianceOf(res.deformed, i);
            double largest = 0, diff = 0;
            for (int r = 0; r < 3; ++r)
                for (int k = 0; k < 3; ++k) {
                    largest = std::max(largest, std::abs(ref[r][k]));
                    diff = std::max(diff, std::abs(got[r][k] - ref[r][k]));
                }
            worst = std::max(worst, diff / largest);
            continue;
        }
        const Quatd q = matrixToQuat(rr0);
        const float* got = res.deformed.rotations.data() + 4 * i;
        const double plus = std::abs(got[0] - q.w) + std::abs(got[1] - q.x) + std::abs(got[2] - q.y) + std::abs(got[3] - q.z);
        const double minus = std::abs(got[0] + q.w) + std::abs(got[1] + q.x) + std::abs(got[2] + q.y) + std::abs(got[3] + q.z);
        worst = std::max(worst, std::min(plus, minus) / 4);
        for (int a = 0; a < 3; ++a) {
            const Vec3d ra(f.r0[0][a], f.r0[1][a], f.r0[2][a]);
            const double ref = double(rest.logScales[3 * i + a]) + std::log(std::max(dot(ra, stretchMat * ra), o.minStretch));
            worst = std::max(worst, relErr(res.deformed.logScales[3 * i + a], ref));
        }
    }
    EXPECT_LT(worst, shape == StageOneShape::Affine ? kAffineTolerance : kFloatTolerance);
}

} // namespace

TEST(StageOneMath, UpdateMatchesPlainReferenceOnBend) { checkAgainstReferenceOnBend(StageOneShape::Polar); }

TEST(StageOneMath, AffineShapeIsTheCovarianceUnderTheLocalMap) { checkAgainstReferenceOnBend(StageOneShape::Affine); }

TEST(StageOneMath, AffineShapeWithEndpointsAtOneSigma) { checkAgainstReferenceOnBend(StageOneShape::Affine, 1.0); }

TEST(StageOneMath, AffineSkinningMatchesSkinPointInGpuLayout)
{
    const GaussianCloud rest = makeDemoModel("stripes", DemoModelOptions{500, 0});
    const DeformationGraph graph = DeformationGraph::build(rest, GraphOptions{32, 6, 0});
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-0.3, 0.3);
    NodeTransforms x = NodeTransforms::identity(graph.nodeCount());
    for (std::size_t j = 0; j < graph.nodeCount(); ++j) {
        for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 3; ++c) x.A[j].m[r][c] += u(rng);
        x.t[j] = Vec3d(u(rng), u(rng), u(rng));
    }
    const SkinWeights w = graph.skinWeights(rest.means.data(), rest.size());
    // The node affines and weights exactly as uploaded to the GPU: flat arrays, host loop.
    const std::vector<NodeAffine> affines = nodeAffines(graph, x);
    double worst = 0.0;
    for (std::size_t q = 0; q < rest.size(); ++q) {
        const Vec3d v(rest.mean(q));
        const Vec3d a = skinAffinePoint(affines.data(), w.nodes.data(), w.weights.data(), std::size_t(w.k), q, v);
        const Vec3d b = skinPoint(graph, x, w, q, v);
        const Mat3d ga = skinAffineGradient(affines.data(), w.nodes.data(), w.weights.data(), std::size_t(w.k), q);
        const Mat3d gb = skinGradient(graph, x, w, q);
        for (int r = 0; r < 3; ++r) {
            worst = std::max(worst, relErr(a[r], b[r]));
            for (int c = 0; c < 3; ++c) worst = std::max(worst, relErr(ga.m[r][c], gb.m[r][c]));
        }
    }
    // Same sums regrouped (A v + b vs A (v - g) + g + t): a few double roundings of values ~1.
    EXPECT_LT(worst, 1e-13);
}

TEST(ShRotationMath, TablesArePlainDataAndRotateLikeShRotation)
{
    // A byte copy of the tables (what the GPU gets) rotates exactly like ShRotation.
    ShRotationTables copy;
    std::memcpy(static_cast<void*>(&copy), &shRotationTables(), sizeof(copy));
    const Mat3d r = quatToMatrix(Quatd{0.3, -0.5, 0.2, 0.8});
    const ShRotation rot(r, 3);
    float a[48], b[48];
    for (int i = 0; i < 48; ++i) a[i] = b[i] = float(std::sin(1.7 * i + 0.2));
    rot.apply(3, a);
    rotateSh(copy, r, 3, b);
    for (int i = 0; i < 48; ++i) EXPECT_EQ(a[i], b[i]) << i;
    // And the rotation is a real one: the colour in direction R d equals the old colour in d.
    float orig[48];
    for (int i = 0; i < 48; ++i) orig[i] = float(std::sin(1.7 * i + 0.2));
    const Vec3d dir(0.2, -0.7, 0.4);
    const Vec3d before = evalShSum<double>(3, orig, dir), after = evalShSum<double>(3, b, r * dir);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(before[c], after[c], 1e-5); // float coefficients
}
