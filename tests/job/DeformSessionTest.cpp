// The session API (the editor's and library users' way into deform): pose without disk, refine
// with progress and a cancel, write what deform writes, byte for byte.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "job/DeformSession.h"
#include "demo/DemoModels.h"
#include "io/GaussianIO.h"
#include "support/TestSupport.h"

using namespace splatwarp;
using namespace splatwarp::test;
namespace fs = std::filesystem;

namespace {

const std::string kSpecs = std::string(SPLATWARP_SOURCE_DIR) + "/samples/specs/";
const char* kFlags = " --nodes 64 --cells 16 --iterations 6 --eval-points 5000";

struct Fixture {
    TempDir dir;
    DeformJobOptions options;
    Fixture()
    {
        DemoModelOptions so;
        so.count = 2000;
        writePly(dir.file("in.ply"), makeDemoModel("stripes", so));
        options.input = dir.file("in.ply");
        options.specPath = kSpecs + "bend.json";
        options.nodes = 64;
        options.grid.cells = 16;
        options.stage2.iterations = 6;
        options.heldOut.points = 5000;
    }
    /// `splatwarp deform` of a spec into dir/NAME with the same settings.
    void deform(const std::string& spec, const std::string& name, const std::string& extra = "") const
    {
        ASSERT_EQ(runCli("-q deform " + options.input + " --spec " + kSpecs + spec + " -o " + dir.file(name) + kFlags + extra,
                         dir.file(name + ".log")),
                  0)
            << fileBytes(dir.file(name + ".log"));
    }
};

} // namespace

TEST(DeformSession, PoseTwiceGivesTheBytesOfStageOneOnly)
{
    Fixture fx;
    fx.deform("bend.json", "cli", " --stage1-only");
    fx.options.stage1Only = true;
    DeformSession session(fx.options, loadDeformSpec(kSpecs + "bend.json"));
    session.pose(loadDeformSpec(kSpecs + "bend.json"));
    session.pose(loadDeformSpec(kSpecs + "bend45-y.json"));
    session.pose(loadDeformSpec(kSpecs + "bend.json")); // posed again after another: the same Stage I
    session.write(fx.dir.file("session"));
    EXPECT_TRUE(fileBytes(fx.dir.file("session/baseline.ply")) == fileBytes(fx.dir.file("cli/baseline.ply")));
    EXPECT_FALSE(fs::exists(fx.dir.file("session/deformed.ply")));
    EXPECT_THROW(session.refine(), UsageError);
}

TEST(DeformSession, PreviewIsStageOneLessTheShAndWriteAfterItIsExact)
{
    Fixture fx;
    fx.deform("bend45-y.json", "cli", " --stage1-only");
    fx.options.stage1Only = true;
    DeformSession session(fx.options, loadDeformSpec(kSpecs + "bend.json")), exact(fx.options, loadDeformSpec(kSpecs + "bend.json"));
    const GaussianCloud& rest = session.rest().model;
    // The first preview solves from rest, as pose does: the same means to float's rounding (the
    // preview's update is float: tests/deform/StageOnePreviewTest.cpp compares its covariances).
    Vec3f lo, hi;
    centreBounds(rest, lo, hi);
    const double extent = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
    const auto worstMean = [&](const GaussianCloud& a, const GaussianCloud& b) {
        double worst = 0.0;
        for (std::size_t i = 0; i < a.means.size(); ++i) worst = std::max(worst, double(std::fabs(a.means[i] - b.means[i])));
        return worst / extent;
    };
    const GaussianCloud cold = session.preview(loadDeformSpec(kSpecs + "bend.json")).cloud;
    const StageOneResult& bend = exact.pose(loadDeformSpec(kSpecs + "bend.json"));
    EXPECT_EQ(cold.shDegree, 0);
    EXPECT_LT(worstMean(cold, bend.deformed), 1e-6);
    EXPECT_TRUE(cold.opacities == rest.opacities);
    for (std::size_t i = 0; i < rest.size(); i += 97)
        for (int c = 0; c < 3; ++c) EXPECT_EQ(cold.sh[3 * i + std::size_t(c)], rest.sh[i * std::size_t(rest.shStride()) + std::size_t(c)]);
    // The next one starts from that solve: within the solver's tolerance of a solve from rest.
    const DeformSession::Preview warm = session.preview(loadDeformSpec(kSpecs + "bend45-y.json"));
    const StageOneResult& other = exact.pose(loadDeformSpec(kSpecs + "bend45-y.json"));
    EXPECT_EQ(warm.moving, other.movingCount);
    const double worst = worstMean(warm.cloud, other.deformed);
    EXPECT_LT(worst, 2e-3);
    // Writing after a preview poses its spec exactly: deform's bytes.
    session.write(fx.dir.file("session"));
    EXPECT_TRUE(fileBytes(fx.dir.file("session/baseline.ply")) == fileBytes(fx.dir.file("cli/baseline.ply")));
    std::printf("preview: warm-started means within %.3g of the model extent\n", worst);
}

TEST(DeformSession, RefineAfterAnotherPoseEqualsDeform)
{
    Fixture fx;
    DeformJobOptions reference = fx.options; // deform's job (the CLI's defaults differ from the struct's: same options here)
    reference.outDir = fx.dir.file("job");
    runDeformJob(reference);
    DeformSession session(fx.options, loadDeformSpec(kSpecs + "bend.json"));
    EXPECT_THROW(session.refine(), UsageError); // no pose yet
    session.pose(loadDeformSpec(kSpecs + "bend45-y.json")); // a drag elsewhere first: the rest side is reused
    session.pose(loadDeformSpec(kSpecs + "bend.json"));
    int calls = 0, last = 0;
    std::vector<std::string> steps; // the phases besides Stage II's iterations, in order
    RunControl control;
    control.onProgress = [&](const std::string& phase, int done, int total) {
        if (phase != "Stage II") {
            EXPECT_EQ(done, int(steps.size())) << phase;
            EXPECT_EQ(total, 7) << phase; // stageTwo() counts the phases of refineSteps() that run
            steps.push_back(phase);
            return;
        }
        EXPECT_EQ(total, 6);
        last = done;
        ++calls;
    };
    session.refine(control);
    EXPECT_GE(calls, 6);
    EXPECT_EQ(last, 6);
    // The steps around Stage II report as they start, so a driver sees the refine move at once.
    EXPECT_EQ(steps, (std::vector<std::string>{"warp", "judge Stage I", "curve split", "validated split", "curve shift", "keep", "judge"}));
    const nlohmann::json report = session.write(fx.dir.file("session")).toJson();
    for (const char* f : {"baseline.ply", "deformed.ply"})
        EXPECT_TRUE(fileBytes(fx.dir.file(std::string("session/") + f)) == fileBytes(fx.dir.file(std::string("job/") + f))) << f;
    EXPECT_TRUE(report.contains("stage2"));
}

TEST(DeformSession, CancelStopsWithinOneIterationAndWritesNothing)
{
    Fixture fx;
    fx.options.stage2.iterations = 50;
    DeformSession session(fx.options, loadDeformSpec(kSpecs + "bend.json"));
    session.pose(loadDeformSpec(kSpecs + "bend.json"));
    std::atomic<bool> cancel{false};
    int seen = 0, afterCancel = 0;
    RunControl control;
    control.cancel = &cancel;
    control.onProgress = [&](const std::string& phase, int done, int) {
        if (phase != "Stage II") return; // the steps before it
        ++seen;
        if (cancel) ++afterCancel;
        if (done == 3) cancel = true;
    };
    EXPECT_THROW(session.refine(control), Cancelled);
    EXPECT_EQ(afterCancel, 0);
    EXPECT_LE(seen, 3 * 3); // every Stage II run the recipe starts stops at its next iteration
    EXPECT_FALSE(session.refined());
    EXPECT_FALSE(fs::exists(fx.dir.file("session")));
    // The pose survives the cancel: refine again without it, then write.
    cancel = false;
    control.onProgress = nullptr;
    session.refine(control);
    session.write(fx.dir.file("session"));
    EXPECT_TRUE(fs::exists(fx.dir.file("session/deformed.ply")));
}

TEST(DeformSession, ASpecWithAnotherGraphIsRefused)
{
    Fixture fx;
    fx.options.stage1Only = true;
    DeformSession session(fx.options, loadDeformSpec(kSpecs + "bend.json"));
    fx.options.nodes.reset();
    DeformSpec other = loadDeformSpec(kSpecs + "bend.json");
    other.graph.nodes = 64;
    EXPECT_NO_THROW(session.pose(other)); // --nodes 64 overrides the spec's count: the same graph
    DeformSession free(fx.options, loadDeformSpec(kSpecs + "bend.json"));
    other.graph.nodes = 17;
    EXPECT_NE(inputErrorMessage([&] { free.pose(other); }).find("differs from the one this session was prepared for"), std::string::npos);
}
