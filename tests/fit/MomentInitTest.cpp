#include <gtest/gtest.h>

#include <cmath>

#include "fit/MomentInit.h"
#include "fit/VolumeFit.h"
#include "fit/OneGaussian.h"

namespace splatwarp {
namespace {

using test::OneGaussian;

/// The one Gaussian initFromMoments() makes of these voxels equals `truth` (moments, alpha, colour).
void expectRecovers(const OneGaussian& truth, const VoxelSamples& voxels, MomentInitOptions o)
{
    o.gaussians = 1;
    const GaussianCloud g = initFromMoments(voxels, o);
    ASSERT_EQ(g.size(), 1u);
    for (int a = 0; a < 3; ++a) EXPECT_NEAR(g.means[std::size_t(a)], truth.mean[a], 1e-5);
    EXPECT_NEAR(g.alpha(0), truth.alpha, 1e-4);
    const Mat3d r = quatToMatrix(Quatd{g.rotations[0], g.rotations[1], g.rotations[2], g.rotations[3]});
    const Mat3d want = truth.cov();
    for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) {
            double got = 0;
            for (int k = 0; k < 3; ++k) got += r.m[a][k] * std::exp(2.0 * g.logScales[std::size_t(k)]) * r.m[b][k];
            EXPECT_NEAR(got, want.m[a][b], 1e-4 * 0.2) << a << "," << b;
        }
    EXPECT_NEAR(g.sh[0], 0.7f, 1e-5);
    EXPECT_NEAR(g.sh[1], -0.2f, 1e-5);
}

// Point samples of a Gaussian much wider than a voxel have exactly its moments (the lattice sum of
// a Gaussian's moments converges like exp(-2 pi^2 sigma^2 / s^2)); the tails to 6 sigma are kept.
TEST(MomentInit, RecoversOneGaussianExactly)
{
    const OneGaussian truth;
    expectRecovers(truth, truth.voxels(28), {});
}

// Our own files hold the field under an isotropic filter of variance f that keeps alpha: the
// samples are those of the same Gaussian with every variance + f. Told f, the moments give the
// unfiltered Gaussian back.
TEST(MomentInit, RecoversTheGaussianUnderTheVolumesFilter)
{
    const OneGaussian truth;
    const double f = 0.03; // a variance of the order of the smallest axis' (0.04)
    OneGaussian filtered = truth;
    for (int k = 0; k < 3; ++k) filtered.scales[k] = std::sqrt(truth.scales[k] * truth.scales[k] + f);
    MomentInitOptions o;
    o.filterVariance = f;
    expectRecovers(truth, filtered.voxels(32), o);
}

TEST(MomentInit, BudgetAndDefault)
{
    const VoxelSamples v = OneGaussian().voxels(10);
    MomentInitOptions o;
    o.gaussians = 37;
    EXPECT_EQ(initFromMoments(v, o).size(), 37u);
    EXPECT_EQ(defaultGaussianBudget(v.size()), v.size() / 8);
    // Mass is kept: the integral of sum alpha G equals the voxels' mass (no cluster needs alpha > 0.99 here).
    const GaussianCloud g = initFromMoments(v, o);
    double mass = 0, model = 0;
    for (float x : v.values) mass += x * std::pow(v.voxelSize, 3);
    for (std::size_t i = 0; i < g.size(); ++i) {
        const Vec3f s = g.scale(i);
        model += g.alpha(i) * std::pow(2 * M_PI, 1.5) * s.x * s.y * s.z;
    }
    EXPECT_NEAR(model / mass, 1.0, 1e-4);
}

TEST(MomentInit, ZeroVoxelsDoNotUseTheBudget)
{
    VoxelSamples v = OneGaussian().voxels(10);
    for (std::size_t i = 0; i < v.size(); ++i) { // an empty half, as in the box of a sparse fog
        if (v.positions[3 * i] >= 0.0f) continue;
        v.values[i] = 0.0f;
        for (int s = 0; s < 3; ++s) v.features[3 * i + std::size_t(s)] = 0.0f;
    }
    MomentInitOptions o;
    o.gaussians = 500;
    EXPECT_EQ(initFromMoments(v, o).size(), 500u);
}

TEST(VolumeFit, PruneAndSplit)
{
    GaussianCloud g;
    g.resize(3, 0);
    g.opacities = {-8.0f, 0.0f, 1.0f};
    EXPECT_EQ(pruneTransparent(g, 1.0f / 255.0f), 1u);
    EXPECT_EQ(g.size(), 2u);
    SampleSet s;
    s.restPositions = {0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f};
    g.means = {0, 0, 0, 5, 5, 5};
    const std::vector<float> residual = {0.5f, 0.5f}; // both near Gaussian 0
    EXPECT_EQ(splitLargestResidual(g, s, residual, 1), 1u);
    ASSERT_EQ(g.size(), 3u);
    // Gaussian 0 became two, offset symmetrically about its old centre.
    EXPECT_NEAR(g.means[0] + g.means[6], 0.0f, 1e-6);
    EXPECT_NEAR(g.means[1] + g.means[7], 0.0f, 1e-6);
    EXPECT_GT(std::fabs(g.means[0] - g.means[6]) + std::fabs(g.means[1] - g.means[7]) + std::fabs(g.means[2] - g.means[8]), 0.1f);
    EXPECT_FLOAT_EQ(g.means[3], 5.0f);
}

} // namespace
} // namespace splatwarp
