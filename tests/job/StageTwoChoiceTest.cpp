#include <gtest/gtest.h>

#include <algorithm>
#include <vector>

#include "DeformPipeline.h"
#include "StageTwoChoice.h"
#include "demo/DemoModels.h"
#include "io/GaussianIO.h"
#include "support/TestSupport.h"

using namespace splatwarp;
using namespace splatwarp::test;

namespace {

/// The stripes bend's Stage I model, its deformation and a validation judge.
struct Fixture {
    TempDir dir;
    std::unique_ptr<DeformRest> rest;
    Deformation deformation;
    GaussianCloud stage1;
    std::unique_ptr<Judge> validation;

    Fixture()
    {
        DemoModelOptions so;
        so.count = 2000;
        writePly(dir.file("in.ply"), makeDemoModel("stripes", so));
        DeformJobOptions o;
        o.input = dir.file("in.ply");
        o.specPath = std::string(SPLATWARP_SOURCE_DIR) + "/samples/specs/bend.json";
        o.nodes = 48;
        o.stage1Only = true;
        const DeformSpec spec = loadDeformSpec(o.specPath);
        rest = prepareDeformRest(o, graphOptionsOf(spec, o));
        deformation = solveDeformation(rest->graph, rest->model, spec, o.ed);
        stage1 = rest->stageOne->apply(deformation.transforms, deformation.nodeMoving).deformed;
        HeldOutOptions h;
        h.points = 20000;
        h.seed = 7;
        validation = std::make_unique<Judge>(rest->model, prepareJudgeRest(rest->model, h), deformation);
    }

    /// Stage I's model with every Gaussian on one side of the median deformed x made invisible.
    GaussianCloud blanked(bool left) const
    {
        std::vector<float> xs;
        for (std::size_t i = 0; i < stage1.size(); ++i) xs.push_back(stage1.mean(i).x);
        std::nth_element(xs.begin(), xs.begin() + std::ptrdiff_t(xs.size() / 2), xs.end());
        const float median = xs[xs.size() / 2];
        GaussianCloud g = stage1;
        for (std::size_t i = 0; i < g.size(); ++i)
            if ((g.mean(i).x < median) == left) g.opacities[i] = -30.0f;
        return g;
    }
};

} // namespace

// Start and fit each wrong on one half: the mix takes each region from the side that is right
// there, and is far better than either.
TEST(StageTwoChoice, TheMixTakesEachRegionFromTheSideThatFitsIt)
{
    const Fixture fx;
    const GaussianCloud start = fx.blanked(true), fit = fx.blanked(false);
    StageTwoChoice c;
    const GaussianCloud kept = chooseStageTwoModel(*fx.validation, start, fit, true, c);
    EXPECT_EQ(c.kept, "mix");
    // Measured: start 1.169, fit 1.138, mix 0.327, Stage I itself 0.314 (the regions astride the
    // median keep one blank half); the fit won 256 of 704 regions.
    EXPECT_LT(c.mix, 0.5 * std::min(c.start, c.fit)) << c.start << " " << c.fit << " " << c.mix;
    EXPECT_LT(c.mix, 1.1 * fx.validation->score(fx.stage1));
    EXPECT_NEAR(fx.validation->score(kept), c.mix, 1e-12);
    EXPECT_GT(c.regionsFit, 0u);
    EXPECT_LT(c.regionsFit, c.regions);
    // Gaussians that are not the same ones on both sides never mix.
    StageTwoChoice d;
    chooseStageTwoModel(*fx.validation, start, fit, false, d);
    EXPECT_NE(d.kept, "mix");
}

// A fit worse everywhere is dropped for its start (the mix takes every region from the start:
// it is the start, not below it).
TEST(StageTwoChoice, AFitWorseThanItsStartIsDropped)
{
    const Fixture fx;
    StageTwoChoice c;
    const GaussianCloud kept = chooseStageTwoModel(*fx.validation, fx.stage1, fx.blanked(true), true, c);
    EXPECT_EQ(c.kept, "start");
    EXPECT_EQ(kept.opacities, fx.stage1.opacities);
    EXPECT_LT(c.start, c.fit);
    StageTwoChoice d;
    chooseStageTwoModel(*fx.validation, fx.blanked(true), fx.stage1, true, d);
    EXPECT_EQ(d.kept, "fit");
}
