#pragma once
/// @file ChoiceFixture.h
/// @brief The stripes bend's Stage I model, its deformation and a validation judge: the shared
///        setting of the Stage II choice tests (StageTwoChoiceTest, GaussianChoiceTest).
#include <algorithm>
#include <memory>
#include <vector>

#include "job/DeformPipeline.h"
#include "job/Judge.h"
#include "demo/DemoModels.h"
#include "io/GaussianIO.h"
#include "support/TestSupport.h"

namespace splatwarp::test {

/// A stripes bar of `count` Gaussians written to dir/in.ply, bent by the sample spec on 48 nodes.
inline DeformJobOptions stripesBend(const TempDir& dir, std::size_t count)
{
    DemoModelOptions so;
    so.count = count;
    writePly(dir.file("in.ply"), makeDemoModel("stripes", so));
    DeformJobOptions o;
    o.input = dir.file("in.ply");
    o.specPath = std::string(SPLATWARP_SOURCE_DIR) + "/samples/specs/bend.json";
    o.nodes = 48;
    return o;
}

/// The stripes bend's Stage I model, its deformation and a validation judge.
struct ChoiceFixture {
    TempDir dir;
    std::unique_ptr<DeformRest> rest;
    Deformation deformation;
    GaussianCloud stage1;
    std::unique_ptr<Judge> validation;

    ChoiceFixture()
    {
        DeformJobOptions o = stripesBend(dir, 2000);
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

} // namespace splatwarp::test
