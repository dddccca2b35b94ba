// The fixed judge: its region and points depend on the rest model alone, no filter, rigid specs.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <set>

#include "job/Judge.h"
#include "deform/DeformSpec.h"
#include "field/PreparedGaussian.h"
#include "demo/DemoModels.h"
#include "../field/FieldTestModels.h"

using namespace splatwarp;

namespace {

const std::string kSpecs = std::string(SPLATWARP_SOURCE_DIR) + "/samples/specs/";

GaussianCloud smallStripes()
{
    DemoModelOptions so;
    so.count = 2000;
    return makeDemoModel("stripes", so);
}

} // namespace

TEST(Judge, RegionIsTheGaussiansBoxesAndOneCellAround)
{
    const GaussianCloud g = test::randomCloud(40, 0, 7);
    const JudgeRegion region = judgeRegion(g);
    const double h = region.cellSize;
    ASSERT_GT(region.size(), 0u);
    // The cell edge: the largest extent of the union of the cutoff boxes over 128 cells.
    Vec3d lo(1e30, 1e30, 1e30), hi = -lo;
    std::vector<PreparedGaussian> prepared = prepareCloud(g, 0.0, kDefaultCutoff);
    for (const PreparedGaussian& p : prepared)
        for (int k = 0; k < 3; ++k) {
            lo[k] = std::min(lo[k], double(p.mean[k] - p.halfExtent[k]));
            hi[k] = std::max(hi[k], double(p.mean[k] + p.halfExtent[k]));
        }
    EXPECT_NEAR(h, std::max(hi.x - lo.x, std::max(hi.y - lo.y, hi.z - lo.z)) / kJudgeRegionCells, 1e-6 * h);
    // Every cell lies within one cell of some Gaussian's box, and every box's cells are in.
    std::set<std::array<std::int64_t, 3>> cells;
    for (std::size_t c = 0; c < region.size(); ++c)
        cells.insert({region.origin[0] + region.cells[3 * c], region.origin[1] + region.cells[3 * c + 1],
                      region.origin[2] + region.cells[3 * c + 2]});
    std::size_t inBox = 0;
    for (const auto& cell : cells) {
        bool near = false, in = false;
        for (const PreparedGaussian& p : prepared) {
            bool n = true, i = true;
            for (int k = 0; k < 3; ++k) {
                const auto a = std::int64_t(std::floor((p.mean[k] - p.halfExtent[k]) / h));
                const auto b = std::int64_t(std::floor((p.mean[k] + p.halfExtent[k]) / h));
                n = n && cell[k] >= a - 1 && cell[k] <= b + 1;
                i = i && cell[k] >= a && cell[k] <= b;
            }
            near = near || n;
            in = in || i;
        }
        EXPECT_TRUE(near);
        inBox += in;
    }
    for (const PreparedGaussian& p : prepared) {
        std::array<std::int64_t, 3> corner;
        for (int k = 0; k < 3; ++k) corner[k] = std::int64_t(std::floor((p.mean[k] + p.halfExtent[k]) / h)) + 1;
        EXPECT_TRUE(cells.count(corner)) << "band cell beyond a box corner";
    }
    EXPECT_LT(inBox, cells.size()); // a band exists
}

TEST(Judge, PointsDependOnTheRestModelAndSeedOnlyAndUseNoFilter)
{
    const GaussianCloud rest = smallStripes();
    HeldOutOptions o;
    o.points = 5000;
    const HeldOutPoints a = drawJudgePoints(rest, o), b = drawJudgePoints(rest, o);
    EXPECT_EQ(a.rest, b.rest);
    EXPECT_EQ(a.features.filterVariance, 0.0f);
    EXPECT_EQ(a.features.cutoff, kDefaultCutoff);
    o.seed = 2;
    EXPECT_NE(drawJudgePoints(rest, o).rest, a.rest);
    // The rest model against itself at rest: zero error, both sides of the split populated.
    const JudgeRest jr = prepareJudgeRest(rest, HeldOutOptions{5000, 1, {}});
    const FieldErrorReport e = evaluateHeldOut(jr.unrotated, rest, jr.points);
    EXPECT_EQ(e.opacity, 0.0);
    EXPECT_GT(e.insidePoints, 500u);
    EXPECT_GT(e.outsidePoints, 500u);
}

// The rest side, evaluated on the Stage II block engine, is the per-point evaluation's to the bit
// (SH degree 2, so the rotated target rotates real coefficients).
TEST(Judge, TheRestSideOnTheBlockEngineIsThePerPointOnes)
{
    const GaussianCloud rest = test::randomCloud(300, 2, 5);
    const DeformSpec spec = loadDeformSpec(kSpecs + "twist.json");
    const DeformationGraph graph = DeformationGraph::build(rest, spec.graph);
    const Deformation d = solveDeformation(graph, rest, spec);
    JudgeRest jr = prepareJudgeRest(rest, HeldOutOptions{4000, 3, {}});
    warpHeldOutPoints(jr.points, d, true);
    for (const bool rotated : {false, true}) {
        const float* rot = rotated ? jr.points.rotations.data() : nullptr;
        const FieldErrorTarget plain = fieldErrorTarget(rest, jr.points.rest.data(), rot, jr.points.size(), jr.points.features);
        const FieldErrorTarget got = rotated ? heldOutTarget(rest, jr.points) : unrotatedTarget(rest, jr.points);
        EXPECT_EQ(got.opacity, plain.opacity);
        EXPECT_EQ(got.features, plain.features);
        EXPECT_EQ(got.sumOpacity, plain.sumOpacity);
        EXPECT_GT(plain.sumOpacity, 0.0);
    }
}

// The validation side's rest features come from draws evaluated in batches: each point must hold
// what the rest model gives it alone, for SH degrees that take all draws in one batch (0) and in
// several (3).
TEST(Judge, TheValidationRestSideIsTheRestModelAtItsPoints)
{
    for (const int degree : {0, 3}) {
        const GaussianCloud rest = test::randomCloud(300, degree, 5);
        const JudgeRest v = prepareValidationRest(rest, HeldOutOptions{20000, 3, {}});
        ASSERT_GT(v.points.size(), 1000u);
        const FieldErrorTarget alone = fieldErrorTarget(rest, v.points.rest.data(), nullptr, v.points.size(), v.points.features);
        EXPECT_EQ(v.unrotated.opacity, alone.opacity) << "degree " << degree;
        EXPECT_EQ(v.unrotated.features, alone.features) << "degree " << degree;
        std::size_t inside = 0;
        for (float o : v.unrotated.opacity) inside += o > 0.0f;
        EXPECT_GT(inside, 0u);
        EXPECT_LT(inside, v.points.size());
    }
}

// Twice the draws keep about twice the points: the first draws keep the same points, weights and
// rest side as a run with only those draws, and the later draws as many again.
TEST(Judge, MoreValidationDrawsKeepTheFirstDrawsPointsAndAsManyAgain)
{
    const GaussianCloud rest = test::randomCloud(300, 1, 5);
    const JudgeRest ten = prepareValidationRest(rest, HeldOutOptions{20000, 3, {}}, kValidationDraws);
    const JudgeRest twenty = prepareValidationRest(rest, HeldOutOptions{20000, 3, {}}, 2 * kValidationDraws);
    const std::size_t n = ten.points.size();
    ASSERT_GT(n, 1000u);
    ASSERT_GT(twenty.points.size(), n);
    const double ratio = double(twenty.points.size()) / double(n);
    EXPECT_GT(ratio, 1.8);
    EXPECT_LT(ratio, 2.2);
    EXPECT_TRUE(std::equal(ten.points.rest.begin(), ten.points.rest.end(), twenty.points.rest.begin()));
    EXPECT_TRUE(std::equal(ten.unrotated.weight.begin(), ten.unrotated.weight.end(), twenty.unrotated.weight.begin()));
    EXPECT_TRUE(std::equal(ten.unrotated.opacity.begin(), ten.unrotated.opacity.end(), twenty.unrotated.opacity.begin()));
    // Each point still stands for the judge's sums: the weighted totals are about the same.
    EXPECT_NEAR(twenty.unrotated.sumOpacity / ten.unrotated.sumOpacity, 2.0, 0.2);
}

// auto: 20 draws for small models, fewer as the model grows, never below the default's 10.
TEST(Judge, AutoValidationDrawsFallWithTheModelsSize)
{
    EXPECT_EQ(autoValidationDraws(0), 2 * kValidationDraws);
    EXPECT_EQ(autoValidationDraws(1000), 2 * kValidationDraws);
    EXPECT_EQ(autoValidationDraws(kValidationWork / 20), 20);
    EXPECT_EQ(autoValidationDraws(kValidationWork / 20 + 1), 19);
    EXPECT_EQ(autoValidationDraws(45624), 13); // the donut
    EXPECT_EQ(autoValidationDraws(kValidationWork / 10), kValidationDraws);
    EXPECT_EQ(autoValidationDraws(90854), kValidationDraws); // guitar
    EXPECT_EQ(autoValidationDraws(10000000), kValidationDraws);
}

// A judge that remembers evaluations gives the same scores and errors as one that does not, hands
// back the remembered evaluation for the same model, and evaluates a model changed in one bit again.
TEST(Judge, RememberedEvaluationsAreTheModelsOwn)
{
    const GaussianCloud rest = test::randomCloud(300, 1, 5);
    const DeformSpec spec = loadDeformSpec(kSpecs + "twist.json");
    const DeformationGraph graph = DeformationGraph::build(rest, spec.graph);
    const Deformation d = solveDeformation(graph, rest, spec);
    const JudgeRest jr = prepareJudgeRest(rest, HeldOutOptions{4000, 3, {}});
    const Judge plain(rest, jr, d);
    Judge remembering(rest, jr, d);
    remembering.rememberEvaluations(std::size_t(1) << 20);
    GaussianCloud a = rest, b = rest;
    b.means[7] = std::nextafter(b.means[7], 1e9f);
    for (const GaussianCloud* m : {&a, &b, &a, &b}) {
        EXPECT_EQ(remembering.pointScores(*m), plain.pointScores(*m));
        EXPECT_EQ(remembering.fieldError(*m).opacity, plain.fieldError(*m).opacity);
    }
    EXPECT_EQ(remembering.evaluate(a), remembering.evaluate(a)); // the same object: remembered
    EXPECT_NE(remembering.evaluate(a), remembering.evaluate(b));
    EXPECT_NE(remembering.evaluate(a)->opacity, remembering.evaluate(b)->opacity);
    EXPECT_NE(plain.evaluate(a), plain.evaluate(a)); // evaluated each time
    // Past the byte budget the oldest is dropped (the newest is always kept).
    remembering.rememberEvaluations(1);
    const auto first = remembering.evaluate(a);
    remembering.evaluate(b);
    EXPECT_NE(remembering.evaluate(a), first);
    // forgetLatest() drops the last one used and no other.
    remembering.rememberEvaluations(std::size_t(1) << 20);
    const auto ea = remembering.evaluate(a), eb = remembering.evaluate(b);
    remembering.forgetLatest();
    EXPECT_EQ(remembering.evaluate(a), ea);
    EXPECT_NE(remembering.evaluate(b), eb);
    EXPECT_EQ(remembering.evaluate(b)->opacity, eb->opacity); // evaluated again: the same values
}

// score() sums as it goes: the same bits as pointScores()' sum in point order, with weights.
TEST(Judge, TheScoreIsThePointScoresSum)
{
    const GaussianCloud rest = test::randomCloud(300, 2, 5);
    const Deformation d = solveDeformation(rest, loadDeformSpec(kSpecs + "bend.json"));
    const Judge judge(rest, prepareValidationRest(rest, HeldOutOptions{4000, 3, {}}), d);
    GaussianCloud m = rest;
    for (float& o : m.opacities) o *= 0.9f;
    const std::vector<double> scores = judge.pointScores(m);
    double sum = 0.0;
    for (double s : scores) sum += s;
    EXPECT_EQ(judge.score(m), sum);
    EXPECT_GT(sum, 0.0);
}

// The validation's rest side holds X only; its judge warps the points and rotates the target as a
// judge of the same points with identity warps filled in does, and keeps no rotations after.
TEST(Judge, AValidationRestSideWithoutWarpsJudgesAsAFullOne)
{
    const GaussianCloud rest = test::randomCloud(300, 2, 5);
    const Deformation d = solveDeformation(rest, loadDeformSpec(kSpecs + "twist.json"));
    const JudgeRest bare = prepareValidationRest(rest, HeldOutOptions{4000, 3, {}});
    EXPECT_TRUE(bare.points.warped.empty());
    EXPECT_TRUE(bare.points.rotations.empty());
    JudgeRest full = bare;
    full.points.warped = full.points.rest;
    full.points.rotations.assign(3 * full.points.rest.size(), 0.0f);
    for (std::size_t p = 0; p < full.points.size(); ++p)
        for (int a = 0; a < 3; ++a) full.points.rotations[9 * p + std::size_t(4 * a)] = 1.0f;
    const Judge a(rest, bare, d), b(rest, full, d);
    EXPECT_EQ(a.points().warped, b.points().warped);
    EXPECT_EQ(a.target().features, b.target().features);
    EXPECT_TRUE(a.points().rotations.empty());
    EXPECT_NE(a.points().warped, a.points().rest); // twisted
    EXPECT_EQ(a.pointScores(rest), b.pointScores(rest));
}

TEST(Judge, RigidSpecsAreRecognisedWithTheirMotion)
{
    const GaussianCloud rest = smallStripes();
    const Deformation rigid = solveDeformation(rest, loadDeformSpec(kSpecs + "rigid.json"));
    const std::optional<RigidMotion> m = rigidMotionOf(rigid);
    ASSERT_TRUE(m);
    // rigid.json: 45 degrees about (1,1,0): the axis stays put, the angle from the trace.
    const Vec3d axis = Vec3d(1, 1, 0) / std::sqrt(2.0);
    EXPECT_LT(length(m->rotation * axis - axis), 1e-9);
    const double cosAngle = (m->rotation.m[0][0] + m->rotation.m[1][1] + m->rotation.m[2][2] - 1.0) / 2.0;
    EXPECT_NEAR(cosAngle, std::cos(M_PI / 4), 1e-9);
    EXPECT_FALSE(rigidMotionOf(solveDeformation(rest, loadDeformSpec(kSpecs + "bend.json"))));
    EXPECT_FALSE(rigidMotionOf(solveDeformation(rest, loadDeformSpec(kSpecs + "twist.json"))));
}
