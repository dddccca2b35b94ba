// The editor's Stage I preview (float, batched eigen-decompositions) against the exact update: the
// same means and covariances to float accuracy, for every shape of deformation the samples have.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

#include "deform/StageOne.h"
#include "demo/DemoModels.h"

using namespace splatwarp;

namespace {

const std::string kSpecs = std::string(SPLATWARP_SOURCE_DIR) + "/samples/specs/";

/// Sigma = R diag(s^2) R^T of Gaussian i.
Mat3d covariance(const GaussianCloud& g, std::size_t i)
{
    const float* q = g.rotations.data() + 4 * i;
    const Mat3d r = quatToMatrix(Quatd{q[0], q[1], q[2], q[3]});
    Mat3d d;
    for (int a = 0; a < 3; ++a) d.m[a][a] = std::exp(2.0 * double(g.logScales[3 * i + std::size_t(a)]));
    return r * d * r.transposed();
}

/// |a - b|_F
double distance(const Mat3d& a, const Mat3d& b)
{
    double sum = 0.0;
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) sum += (a.m[r][c] - b.m[r][c]) * (a.m[r][c] - b.m[r][c]);
    return std::sqrt(sum);
}

struct Worst {
    double mean = 0.0;       ///< |mean - exact| / extent
    double covariance = 0.0; ///< |Sigma - exact|_F / |exact|_F
};

/// The preview and the exact update of one spec on one model.
Worst compare(const GaussianCloud& rest, const std::string& spec, StageOneShape shape)
{
    DeformSpec s = loadDeformSpec(kSpecs + spec);
    s.graph.nodes = 64;
    const Deformation d = solveDeformation(rest, s);
    StageOneOptions o;
    o.shape = shape;
    const StageOneRig rig = prepareStageOne(rest, d.graph, o);
    const StageOneResult exact = applyStageOneCpu(rest, rig, d.graph, d.transforms, d.nodeMoving, o);
    GaussianCloud preview = withShDegree(rest, 0);
    const std::size_t moving = applyStageOnePreview(rest, rig, d.graph, d.transforms, d.nodeMoving, o, preview);
    EXPECT_EQ(moving, exact.movingCount) << spec;
    Worst w;
    for (std::size_t i = 0; i < rest.size(); ++i) {
        for (int a = 0; a < 3; ++a)
            w.mean = std::max(w.mean, std::fabs(double(preview.means[3 * i + std::size_t(a)]) -
                                                double(exact.deformed.means[3 * i + std::size_t(a)])) / rig.extent);
        const Mat3d e = covariance(exact.deformed, i);
        w.covariance = std::max(w.covariance, distance(covariance(preview, i), e) / distance(e, Mat3d()));
    }
    return w;
}

/// Random Gaussians in a 4 x 1 x 1 bar, any orientation, scales 1:1 up to 1:100 (needles and disks).
GaussianCloud anisotropicModel(std::size_t n)
{
    GaussianCloud g;
    g.resize(n, 0);
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f), logRatio(0.0f, std::log(100.0f));
    std::normal_distribution<float> normal;
    for (std::size_t i = 0; i < n; ++i) {
        g.means[3 * i] = 2.0f * u(rng);
        g.means[3 * i + 1] = 0.5f * u(rng);
        g.means[3 * i + 2] = 0.5f * u(rng);
        for (int c = 0; c < 4; ++c) g.rotations[4 * i + std::size_t(c)] = normal(rng);
        const float base = std::log(0.03f);
        g.logScales[3 * i] = base;
        g.logScales[3 * i + 1] = base - logRatio(rng);
        g.logScales[3 * i + 2] = base - logRatio(rng);
        g.opacities[i] = 1.0f;
    }
    return g;
}

} // namespace

TEST(StageOnePreview, MeansAndCovariancesAreTheExactUpdatesToFloat)
{
    const GaussianCloud stripes = makeDemoModel("stripes", DemoModelOptions{3000, 2});
    const GaussianCloud needles = anisotropicModel(3000);
    for (const char* spec : {"bend.json", "twist.json", "stretch.json", "squash.json"})
        for (const StageOneShape shape : {StageOneShape::Affine, StageOneShape::Polar})
            for (const GaussianCloud* model : {&stripes, &needles}) {
                const Worst w = compare(*model, spec, shape);
                const char* name = model == &stripes ? "stripes" : "needles";
                std::printf("%s %s %s: mean %.2g of the extent, covariance %.2g relative\n", name, spec,
                            shape == StageOneShape::Affine ? "affine" : "polar", w.mean, w.covariance);
                // Measured: means within 2.4e-7 of the extent (float's rounding); affine
                // covariances within 1.6e-5, where two Jacobi sweeps instead of four leave up to
                // 3.9e-3 on the needles; polar ones within 2.5e-4 (the rotation is then the polar
                // frame itself, and the needles' thin axes span ~1e-3 in float positions ~2).
                EXPECT_LT(w.mean, 1e-6) << name << " " << spec;
                EXPECT_LT(w.covariance, shape == StageOneShape::Affine ? 1e-4 : 1e-3) << name << " " << spec;
            }
}

TEST(StageOnePreview, GaussiansThatStopMovingReadAsRestAgain)
{
    const GaussianCloud rest = makeDemoModel("stripes", DemoModelOptions{2000, 3});
    DeformSpec s = loadDeformSpec(kSpecs + "bend.json");
    s.graph.nodes = 48;
    const Deformation d = solveDeformation(rest, s);
    const StageOneRig rig = prepareStageOne(rest, d.graph);
    GaussianCloud preview = withShDegree(rest, 0);
    ASSERT_GT(applyStageOnePreview(rest, rig, d.graph, d.transforms, d.nodeMoving, {}, preview), 0u);
    const std::vector<std::uint8_t> still(d.graph.nodeCount(), 0);
    EXPECT_EQ(applyStageOnePreview(rest, rig, d.graph, d.transforms, still, {}, preview), 0u);
    EXPECT_TRUE(preview.means == rest.means);
    EXPECT_TRUE(preview.rotations == rest.rotations);
    EXPECT_TRUE(preview.logScales == rest.logScales);
    GaussianCloud wrong = withShDegree(rest, 1);
    EXPECT_THROW(applyStageOnePreview(rest, rig, d.graph, d.transforms, d.nodeMoving, {}, wrong), UsageError);
}
