#include <gtest/gtest.h>

#include <cmath>

#include "FromVdb.h"
#include "SampleGrid.h"
#include "VdbExport.h"
#include "field/FieldTestModels.h"
#include "fit/OneGaussian.h"
#include "render/Rasterizer.h"
#include "support/TestSupport.h"

namespace splatwarp {
namespace {

using test::OneGaussian;
using test::TempDir;

/// The Gaussian's values on voxels (i,j,k) in [-half, half]^3.
DenseGrid gaussianGrid(const OneGaussian& g, int half)
{
    DenseGrid d;
    d.voxelSize = g.s;
    for (int a = 0; a < 3; ++a) {
        d.origin[a] = -half;
        d.dims[a] = 2 * half + 1;
    }
    for (int k = -half; k <= half; ++k)
        for (int j = -half; j <= half; ++j)
            for (int i = -half; i <= half; ++i) d.values.push_back(float(g.value(Vec3d(i * g.s, j * g.s, k * g.s))));
    return d;
}

FromVdbOptions fieldOptions(std::size_t gaussians, int iterations)
{
    FromVdbOptions o = defaultFromVdbOptions();
    o.meaning = VolumeMeaning::Field;
    o.gaussians = gaussians;
    o.fitting.iterations = iterations;
    o.fit = iterations > 0;
    o.judge.points = 20000;
    o.samplesPerAxis = 1; // the grids here are smooth at the voxel scale: voxel centres suffice (fast)
    return o;
}

TEST(FromVdb, RecoversOneGaussianWrittenToAGrid)
{
    const OneGaussian truth;
    TempDir dir;
    writeDenseGrids(dir.file("g.vdb"), {gaussianGrid(truth, 28)});
    const Volume volume = readVolume(dir.file("g.vdb"));
    EXPECT_EQ(volume.info().grid, "density");
    EXPECT_FALSE(volume.info().ownFile);
    EXPECT_EQ(resolveMeaning(VolumeMeaning::Auto, volume), VolumeMeaning::Extinction);
    const FromVdbResult r = fromVdb(volume, fieldOptions(1, 0));
    ASSERT_EQ(r.splats.size(), 1u);
    for (int a = 0; a < 3; ++a) EXPECT_NEAR(r.splats.means[std::size_t(a)], truth.mean[a], 1e-5);
    EXPECT_NEAR(r.splats.alpha(0), truth.alpha, 1e-4);
    std::vector<double> want = {truth.scales.x, truth.scales.y, truth.scales.z}, got;
    for (int a = 0; a < 3; ++a) got.push_back(std::exp(r.splats.logScales[std::size_t(a)]));
    std::sort(want.begin(), want.end());
    std::sort(got.begin(), got.end());
    for (int a = 0; a < 3; ++a) EXPECT_NEAR(got[std::size_t(a)], want[std::size_t(a)], 1e-4);
    // The held-out error of the exact Gaussian is what the model's 1/255 cutoff drops: the tail
    // of the grid beyond alpha*G = 1/255 (a few per cent of the mass) and trilinear rounding.
    const double noFit = r.report["held_out"]["no_fit"]["opacity"];
    EXPECT_LT(noFit, 0.05);
    // The fit starts at the answer; with the best iterate kept it cannot leave it far.
    const FromVdbResult fitted = fromVdb(volume, fieldOptions(1, 20));
    EXPECT_LE(double(fitted.report["held_out"]["fit"]["opacity"]), noFit * 1.1);
}

TEST(FromVdb, RoundTripOfAGeneratedModel)
{
    const GaussianCloud original = test::randomCloud(60, 1, 7, 1.0f, 0.08f, 0.25f);
    SampleGridOptions go;
    go.cells = 12;
    const SampleGrid grid(original, go);
    TempDir dir;
    VdbExportOptions vo;
    vo.shGrids = true;
    writeSampleGridVdb(dir.file("m.vdb"), grid, vo);
    const Volume volume = readVolume(dir.file("m.vdb"));
    EXPECT_TRUE(volume.info().ownFile);
    EXPECT_EQ(volume.info().shDegree, 1);
    EXPECT_EQ(resolveMeaning(VolumeMeaning::Auto, volume), VolumeMeaning::Field);
    const FromVdbResult init = fromVdb(volume, fieldOptions(original.size(), 0));
    const FromVdbResult fit = fromVdb(volume, fieldOptions(original.size(), 100));
    EXPECT_LE(fit.splats.size(), original.size());
    EXPECT_EQ(fit.splats.shDegree, 1);
    // Against the original splats (both unfiltered) at held-out points of the volume.
    const std::vector<float> pts = volume.heldOutPoints(20000, 3, 2);
    const std::size_t p = pts.size() / 3;
    const FieldErrorReport eInit = fieldError(original, init.splats, pts.data(), pts.data(), nullptr, p);
    const FieldErrorReport eFit = fieldError(original, fit.splats, pts.data(), pts.data(), nullptr, p);
    // Measured: init 0.554, fit 0.358 (opacity). The 0.15 is NOT reached on this model of
    // large overlapping Gaussians in 100 iterations; this guards the direction and a clear gain.
    EXPECT_LT(eFit.opacity, 0.75 * eInit.opacity) << "init " << eInit.opacity << " fit " << eFit.opacity;
    EXPECT_LT(eFit.color, eInit.color);
}

// A uniform slab of extinction sigma and thickness L transmits exp(-sigma L) straight through.
// The splats' transmittance (extinction converted to opacity, composited by the rasteriser) must
// match it at the slab's centre; the tolerance records the approximation (see fit/Extinction.h).
TEST(FromVdb, ExtinctionSlabMatchesAnalyticTransmittance)
{
    const double s = 0.05, sigma = 2.0;
    DenseGrid d;
    d.voxelSize = s;
    d.dims[0] = d.dims[1] = 32;
    d.dims[2] = 10; // L = 0.5: sigma L = 1
    d.values.assign(std::size_t(32 * 32 * 10), float(sigma));
    TempDir dir;
    writeDenseGrids(dir.file("slab.vdb"), {d});
    const Volume volume = readVolume(dir.file("slab.vdb"));
    const double exact = std::exp(-sigma * 10 * s);
    // Look down the z axis from far away at the slab's centre.
    const Vec3d c(15.5 * s, 15.5 * s, 4.5 * s);
    const Camera cam = Camera::lookAt(c + Vec3d(0, 0, 40.0), c, Vec3d(0, 1, 0), 0.5, 32, 32);
    auto transmittance = [&](double densityScale) {
        FromVdbOptions o = defaultFromVdbOptions();
        o.fitting.iterations = 60;
        o.judge.points = 20000;
        o.samplesPerAxis = 1; // uniform: the trilinear field is constant inside
        o.densityScale = densityScale;
        const FromVdbResult r = fromVdb(volume, o);
        EXPECT_EQ(r.report["as"], "extinction");
        const Image splats = renderGaussians(r.splats, cam);
        double sum = 0;
        for (int y = 8; y < 24; ++y)
            for (int x = 8; x < 24; ++x) sum += 1.0 - splats.at(x, y, 3);
        return sum / 256.0;
    };
    // Measured against exp(-1) = 0.368, with the fit defaults of the engine (boundary weight 99,
    // scale rate 5e-3): 0.399 with the density scale at the maximum, 0.443 at the default quarter
    // of it (the skirts transmit too much). With from-vdb's own defaults (boundary weight 2, scale
    // rate 2e-2) the fitted splats turn anisotropic and the conversion, which uses the geometric
    // mean of the scales, makes them too opaque seen along their thin axis: 0.298 and 0.250
    // (0.256 and 0.259 with the boundary weight kept at 99).
    const double tMax = transmittance(sigma), tDefault = transmittance(0.0);
    EXPECT_NEAR(tMax, exact, 0.1) << "splat transmittance " << tMax << " exact " << exact;
    EXPECT_NEAR(tDefault, exact, 0.14) << "splat transmittance " << tDefault << " exact " << exact;
    RecordProperty("splat_transmittance_scale_max", std::to_string(tMax));
    RecordProperty("splat_transmittance_default", std::to_string(tDefault));
}

} // namespace
} // namespace splatwarp
