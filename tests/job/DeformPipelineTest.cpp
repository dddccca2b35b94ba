#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "job/DeformPipeline.h"
#include "deform/WarpDevice.h"
#include "io/GaussianIO.h"
#include "demo/DemoModels.h"
#include "support/TestSupport.h"

using namespace splatwarp;
using namespace splatwarp::test;

namespace {

const std::string kSpecs = std::string(SPLATWARP_SOURCE_DIR) + "/samples/specs/";

/// A small stripes bar and a coarse grid, so a whole deform run takes ~2 s.
DeformJobOptions smallJob(const TempDir& dir, const std::string& spec, int iterations)
{
    DemoModelOptions so;
    so.count = 3000;
    writePly(dir.file("in.ply"), makeDemoModel("stripes", so));
    DeformJobOptions o;
    o.input = dir.file("in.ply");
    o.specPath = kSpecs + spec;
    o.outDir = dir.file("out");
    o.nodes = 64;
    o.grid.cells = 20;
    o.stage2.iterations = iterations;
    o.heldOut.points = 20000;
    return o;
}

/// The energies of the iterates a Stage II run held (rejected steps aside) never rise.
void expectNoClimb(const nlohmann::json& stage2)
{
    double held = stage2["energies"].at(0)["total"].get<double>();
    for (const auto& e : stage2["energies"]) {
        if (e["rejected"].get<bool>()) continue;
        EXPECT_LE(e["total"].get<double>(), held) << "iteration " << e["iteration"];
        held = e["total"].get<double>();
    }
}

double err(const nlohmann::json& r, const char* stage, const char* what) { return r[stage]["fieldError"][what].get<double>(); }

/// What `splatwarp ARGS` (with --json) prints, parsed.
nlohmann::json evalJson(const TempDir& dir, const std::string& args)
{
    const std::string out = dir.file("eval.json");
    EXPECT_EQ(runCli(args, out), 0) << args;
    std::ifstream in(out);
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    return nlohmann::json::parse(text.substr(std::min(text.find('{'), text.size())));
}

} // namespace

TEST(DeformPipeline, StageTwoLowersTheFieldErrorOnTheStripesBend)
{
    TempDir dir;
    DeformJobOptions o = smallJob(dir, "bend.json", 30);
    o.stage1.shape = StageOneShape::Polar; // the paper's Stage I, whose shapes Stage II corrects
    o.curveSplit = false;                  // the paper's Stage II: its fit alone, kept whatever it gives
    o.keepValidated = false;
    const nlohmann::json r = runDeformJob(o).toJson();
    for (const char* f : {"baseline.ply", "deformed.ply", "report.json"})
        EXPECT_TRUE(std::filesystem::exists(dir.file("out") + "/" + f)) << f;
    // The energy falls: measured 3115 -> 874 over 30 iterations.
    const auto& energies = r["stage2"]["energies"];
    ASSERT_GE(energies.size(), 2u);
    EXPECT_LT(r["stage2"]["bestEnergy"].get<double>(), 0.5 * energies.front()["total"].get<double>());
    // The judge, measured: opacity 0.170 -> 0.137 (ratio 0.81), colour 0.178 -> 0.139 (0.78); at the
    // training lattice (what Stage II fits) 0.0393 -> 0.0237 (0.60), colour 0.0409 -> 0.0233 (0.57).
    EXPECT_LT(err(r, "stage2", "opacity"), 0.9 * err(r, "stage1", "opacity"));
    EXPECT_LT(err(r, "stage2", "color"), 0.9 * err(r, "stage1", "color"));
    auto lattice = [&](const char* stage, const char* what) { return r[stage]["latticeError"][what].get<double>(); };
    EXPECT_LT(lattice("stage2", "opacity"), 0.8 * lattice("stage1", "opacity"));
    EXPECT_LT(lattice("stage2", "color"), 0.8 * lattice("stage1", "color"));
    expectNoClimb(r["stage2"]);
    EXPECT_GT(r["stage2"]["samples"].get<double>(), 0.0);
    EXPECT_GT(r["stage2"]["pairsPerIteration"].get<double>(), 0.0);
    // The report on disk is the one returned.
    std::ifstream in(dir.file("out") + "/report.json");
    EXPECT_EQ(nlohmann::json::parse(in), r);
}

TEST(DeformPipeline, AffineStageOneLowersTheJudgedErrorAndStageTwoStillLowersIt)
{
    TempDir polarDir, affineDir;
    DeformJobOptions polar = smallJob(polarDir, "bend.json", 30);
    polar.stage1.shape = StageOneShape::Polar;
    const nlohmann::json p = runDeformJob(polar).toJson();
    const nlohmann::json a = runDeformJob(smallJob(affineDir, "bend.json", 30)).toJson(); // the default: affine
    EXPECT_EQ(a["stage1"]["shape"], "affine");
    EXPECT_EQ(p["stage1"]["shape"], "polar");
    // Measured: Stage I opacity 0.170 (polar) -> 0.141 (affine), colour 0.178 -> 0.139; Stage II from
    // the affine start 0.128 / 0.128.
    for (const char* what : {"opacity", "color"}) {
        EXPECT_LT(err(a, "stage1", what), 0.9 * err(p, "stage1", what)) << what;
        EXPECT_LT(err(a, "stage2", what), err(a, "stage1", what)) << what;
    }
    expectNoClimb(a["stage2"]);
}

// The defaults split the bent Gaussians before Stage II (--curve-split auto) and keep the start,
// the fit or their mix, whichever the validation points judge best (--keep validated).
TEST(DeformPipeline, CurveSplitAndTheValidatedKeepAtTheDefaults)
{
    TempDir dir;
    const DeformJobOptions o = smallJob(dir, "bend.json", 30);
    const nlohmann::json r = runDeformJob(o).toJson();
    const std::size_t input = readGaussians(o.input).size();
    const std::size_t curveAdded = r["curveSplit"]["added"].get<std::size_t>();
    EXPECT_GT(curveAdded, 0u);
    EXPECT_EQ(r["curveSplit"]["gaussians"].get<std::size_t>(), input + curveAdded);
    const nlohmann::json& vs = r["validatedSplit"];
    EXPECT_EQ(vs["added"].get<std::size_t>(), 2 * vs["split"].get<std::size_t>());
    EXPECT_LE(vs["added"].get<std::size_t>(), vs["budget"].get<std::size_t>());
    const std::size_t added = curveAdded + vs["added"].get<std::size_t>();
    EXPECT_EQ(r["stage2"]["gaussiansAdded"].get<std::size_t>(), added);
    // The 1.5x budget is met after the keep: the splits went past it, the merge took them back.
    const std::size_t limit = input * 3 / 2, removed = r["stage2"]["budgetMerge"]["removed"].get<std::size_t>();
    EXPECT_GT(input + added, limit);
    EXPECT_EQ(r["stage2"]["gaussiansRemoved"].get<std::size_t>(), removed);
    EXPECT_EQ(r["stage2"]["gaussians"].get<std::size_t>(), input + added - removed);
    EXPECT_LE(input + added - removed, limit);
    EXPECT_EQ(readGaussians(o.outDir + "/deformed.ply").size(), input + added - removed);
    EXPECT_EQ(readGaussians(o.outDir + "/baseline.ply").size(), input);
    // The split with fans or without, whichever the validation points judge better (here the
    // same: no Gaussian of the stripes is bent beyond kFanAbove; both 0.1687).
    const nlohmann::json& cs = r["curveSplit"];
    const bool fans = cs["validationWithFans"].get<double>() <= cs["validationWithoutFans"].get<double>();
    EXPECT_EQ(cs["fans"], fans ? "on" : "off (validated)");
    const nlohmann::json& keep = r["stage2"]["keep"];
    const double start = keep["validationStart"].get<double>(), fit = keep["validationFit"].get<double>(),
                 shifted = keep["validationShifted"].get<double>(), mix = keep["validationMix"].get<double>();
    const double best = std::min({start, shifted, fit});
    const std::string kept = keep["kept"].get<std::string>();
    EXPECT_EQ(kept, mix < best ? "mix" : (start == best ? "start" : (shifted == best ? "shifted" : "fit")));
    // Then each Gaussian's version: from the kept model's score down.
    const nlohmann::json& each = keep["perGaussian"];
    EXPECT_NEAR(each["validationBefore"].get<double>(), std::min(best, mix), 1e-6 * best);
    EXPECT_LE(each["validationAfter"].get<double>(), each["validationBefore"].get<double>());
    EXPECT_LE(each["swapped"].get<std::size_t>(), each["tried"].get<std::size_t>());
    // The curve shift: the share whose shifted start the validation points judge best.
    const nlohmann::json& shift = r["curveShift"];
    double lowest = INFINITY;
    for (const auto& [share, score] : shift["validation"].items()) lowest = std::min(lowest, score.get<double>());
    EXPECT_EQ(shift["validation"][msg(shift["share"].get<double>())].get<double>(), lowest);
    EXPECT_NEAR(keep["validationShifted"].get<double>(), lowest, 1e-12);
    // Measured (judge, opacity): Stage I 0.141, curve split 0.086, kept (the mix, fit in 116 of 727
    // regions) 0.084; validation start 0.169, fit 0.218, mix 0.155.
    EXPECT_LT(r["curveSplit"]["fieldError"]["opacity"].get<double>(), 0.8 * err(r, "stage1", "opacity"));
    for (const char* what : {"opacity", "color"}) EXPECT_LT(err(r, "stage2", what), 0.8 * err(r, "stage1", what)) << what;
    // --keep regions --validated-split off: neither step runs.
    DeformJobOptions off = o;
    off.outDir = dir.file("off");
    off.keepPerGaussian = false;
    off.validatedSplit = false;
    const nlohmann::json q = runDeformJob(off).toJson();
    EXPECT_FALSE(q.contains("validatedSplit"));
    EXPECT_FALSE(q["stage2"]["keep"].contains("perGaussian"));
    EXPECT_EQ(q["stage2"]["gaussians"].get<std::size_t>(),
              input + q["curveSplit"]["added"].get<std::size_t>() - q["stage2"]["budgetMerge"]["removed"].get<std::size_t>());
}

// --validation-stop: Stage II's fit is scored on the keep's validation points after two steps and
// every K iterations, and stops once the score no longer falls; the keep then scores that same
// iterate.
TEST(DeformPipeline, TheValidationStopEndsStageTwoWhenTheFitStopsImproving)
{
    TempDir dir;
    DeformJobOptions o = smallJob(dir, "bend.json", 30);
    o.validationStop = 5;
    const nlohmann::json r = runDeformJob(o).toJson();
    const nlohmann::json& s2 = r["stage2"];
    const nlohmann::json& checks = s2["validationChecks"];
    // Measured: the start's score 0.156, then 0.148 and 0.141 at 2 and 5 (each below the last),
    // then 0.144 at 10: the run stops at 10 of 30.
    ASSERT_GE(checks.size(), 3u);
    const int stopped = s2["stoppedAt"].get<int>();
    EXPECT_EQ(stopped, checks.back()["iteration"].get<int>());
    EXPECT_LT(stopped, 30);
    EXPECT_EQ(s2["stopReason"], "the validation score rose");
    for (std::size_t i = 0; i < checks.size(); ++i) {
        EXPECT_EQ(checks[i]["iteration"].get<int>(), i == 0 ? 0 : i == 1 ? 2 : int(5 * (i - 1)));
        if (i == 0) continue;
        const double before = checks[i - 1]["score"].get<double>(), now = checks[i]["score"].get<double>();
        if (i + 1 < checks.size())
            EXPECT_LT(now, before) << "check " << i;
        else
            EXPECT_GE(now, before);
    }
    EXPECT_EQ(s2["energies"].back()["iteration"].get<int>(), stopped);
    EXPECT_DOUBLE_EQ(s2["keep"]["validationFit"].get<double>(), checks.back()["score"].get<double>());
    // The first check is the start the keep scores too: the same model, the same score.
    EXPECT_DOUBLE_EQ(s2["keep"]["validationStart"].get<double>(), checks.front()["score"].get<double>());
    // 0 (and a keep without validation points) never scores: every iteration runs.
    for (const bool keep : {true, false}) {
        DeformJobOptions off = o;
        off.outDir = dir.file(keep ? "off" : "fit");
        off.validationStop = keep ? 0 : 5;
        off.keepValidated = keep;
        off.keepPerGaussian = keep;
        off.validatedSplit = keep;
        const nlohmann::json q = runDeformJob(off).toJson();
        EXPECT_TRUE(q["stage2"]["validationChecks"].empty()) << keep;
        EXPECT_EQ(q["stage2"]["stoppedAt"].get<int>(), -1) << keep;
        EXPECT_EQ(q["stage2"]["energies"].back()["iteration"].get<int>(), 30) << keep;
    }
}

TEST(DeformPipeline, RigidSpecStageTwoDoesNotRaiseTheError)
{
    TempDir dir;
    const nlohmann::json r = runDeformJob(smallJob(dir, "rigid.json", 20)).toJson();
    // Stage I is exact for a rigid spec: Stage II is skipped and deformed.ply is the Stage I model.
    EXPECT_EQ(r["stage2"]["skipped"], "rigid spec");
    EXPECT_EQ(fileBytes(dir.file("out") + "/deformed.ply"), fileBytes(dir.file("out") + "/baseline.ply"));
    // Stage I is exact for a rigid motion up to float rounding and the ED solver's tolerance
    // (judge measured 2.7e-6; 5.6e-7 at the training lattice, whose filter hides more).
    EXPECT_LT(err(r, "stage1", "opacity"), 1e-5);
    // Against the known ground truth (the rest model from the inversely moved cameras): measured 139 dB.
    ASSERT_TRUE(r["stage1"]["fieldError"].contains("imagePsnr"));
    EXPECT_GT(r["stage1"]["fieldError"]["imagePsnr"]["db"].get<double>(), 100.0);
    EXPECT_GT(r["stage2"]["fieldError"]["imagePsnr"]["db"].get<double>(), 100.0);
    EXPECT_LE(err(r, "stage2", "opacity"), err(r, "stage1", "opacity") + 1e-6);
    EXPECT_LE(err(r, "stage2", "color"), err(r, "stage1", "color") + 1e-6);
}

TEST(DeformPipeline, TheJudgeIgnoresTrainingFlagsAndEvalPrintsTheReport)
{
    TempDir dir;
    const DeformJobOptions a = smallJob(dir, "bend.json", 2);
    const nlohmann::json ra = runDeformJob(a).toJson();
    DeformJobOptions b = a;
    b.outDir = dir.file("out12");
    b.grid.cells = 12;
    b.grid.samplesPerAxis = kAutoSamplesPerAxis; // the CLI's default
    const nlohmann::json rb = runDeformJob(b).toJson();
    // Stage I does not depend on the lattice: the same baseline.ply, judged the same; the error
    // at the training lattice does depend on it.
    EXPECT_EQ(ra["stage1"]["fieldError"], rb["stage1"]["fieldError"]);
    EXPECT_NE(ra["stage1"]["latticeError"]["opacity"], rb["stage1"]["latticeError"]["opacity"]);
    EXPECT_FALSE(ra["stage1"]["fieldError"].contains("imagePsnr")); // a bend is not rigid
    // eval on the written files prints the reports' numbers (the run's graph override is part
    // of the deformation: eval takes it too).
    const std::string eval =
        "-q eval --rest " + a.input + " --spec " + a.specPath + " --nodes 64 --points 20000 --json --deformed ";
    EXPECT_EQ(evalJson(dir, eval + a.outDir + "/baseline.ply"), ra["stage1"]["fieldError"]);
    EXPECT_EQ(evalJson(dir, eval + a.outDir + "/deformed.ply"), ra["stage2"]["fieldError"]);
    EXPECT_EQ(evalJson(dir, eval + b.outDir + "/deformed.ply"), rb["stage2"]["fieldError"]);
    // A lattice flag without --lattice is a usage error; with it, eval gives the lattice error
    // (same graph, lattice and points as run a).
    EXPECT_EQ(runCli(eval + a.outDir + "/baseline.ply --cells 20"), 2);
    const nlohmann::json lattice = evalJson(dir, eval + a.outDir + "/baseline.ply --lattice --cells 20 --samples-per-cell 4");
    EXPECT_EQ(lattice["opacity"], ra["stage1"]["latticeError"]["opacity"]);
    EXPECT_EQ(lattice["color"], ra["stage1"]["latticeError"]["color"]);
    // --samples-per-cell auto (both commands' default) resolves to the same lattice in eval as in deform.
    EXPECT_GT(rb["stage2"]["samplesPerCell"].get<int>(), 4);
    const nlohmann::json autoLattice = evalJson(dir, eval + b.outDir + "/deformed.ply --lattice --cells 12");
    EXPECT_EQ(autoLattice["opacity"], rb["stage2"]["latticeError"]["opacity"]);
    // A missing spec file is bad input: exit 1.
    EXPECT_EQ(runCli("eval --rest " + a.input + " --deformed " + a.outDir + "/baseline.ply --spec " + dir.file("missing.json")), 1);
}

// --fine-cells from the command line: auto refines some cells, and the report's sample count is
// the uniform n^3 per active cell plus (2n)^3 - n^3 per fine cell; off refines none.
TEST(DeformPipeline, FineCellsFromTheCommandLine)
{
    TempDir dir;
    const DeformJobOptions a = smallJob(dir, "bend.json", 1);
    const std::string base = "-q deform " + a.input + " --spec " + a.specPath + " --nodes 64 --cells 20 --iterations 1 "
                             "--samples-per-cell 4 --no-eval --eval-points 5000 --device cpu --fine-cells ";
    auto stage2 = [&](const std::string& mode) {
        const std::string out = dir.file("out-" + mode);
        EXPECT_EQ(runCli(base + mode + " -o " + out), 0) << mode;
        std::ifstream in(out + "/report.json");
        return nlohmann::json::parse(in)["stage2"];
    };
    const nlohmann::json fine = stage2("auto"), uniform = stage2("off");
    const int n3 = 4 * 4 * 4, fine3 = 8 * 8 * 8;
    EXPECT_GT(fine["fineCells"].get<std::size_t>(), 0u);
    EXPECT_EQ(fine["fineSamplesAdded"].get<std::size_t>(), fine["fineCells"].get<std::size_t>() * (fine3 - n3));
    EXPECT_EQ(fine["samples"].get<std::size_t>(),
              fine["activeCells"].get<std::size_t>() * n3 + fine["fineSamplesAdded"].get<std::size_t>());
    EXPECT_EQ(uniform["fineCells"].get<std::size_t>(), 0u);
    EXPECT_EQ(uniform["samples"].get<std::size_t>(), uniform["activeCells"].get<std::size_t>() * n3);
    EXPECT_EQ(runCli(base + "sometimes -o " + dir.file("bad")), 2);
}

// --split auto and --prune-below from the command line: the report's counts add up and match the
// written deformed.ply; bad values are usage errors.
TEST(DeformPipeline, SplitAndPruneFromTheCommandLine)
{
    TempDir dir;
    const DeformJobOptions a = smallJob(dir, "stretch.json", 1);
    const std::string base = "-q deform " + a.input + " --spec " + a.specPath + " --nodes 64 --cells 20 --iterations 6 "
                             "--no-eval --eval-points 5000 --device cpu --curve-split off --keep fit ";
    auto run = [&](const std::string& flags, const std::string& name) {
        const std::string out = dir.file(name);
        EXPECT_EQ(runCli(base + flags + " -o " + out), 0) << flags;
        std::ifstream in(out + "/report.json");
        return nlohmann::json::parse(in);
    };
    const std::size_t input = readGaussians(a.input).size();
    const nlohmann::json off = run("", "off");
    EXPECT_EQ(off["stage2"]["gaussiansAdded"].get<std::size_t>(), 0u);
    EXPECT_EQ(off["stage2"]["gaussiansRemoved"].get<std::size_t>(), 0u);
    EXPECT_EQ(off["stage2"]["gaussians"].get<std::size_t>(), input);
    // The stretch pulls the +x end out by 30%: its cells' F exceed 1.1.
    const nlohmann::json r = run("--split auto --split-stretch 1.1 --prune-below 0.05", "split");
    const std::size_t added = r["stage2"]["gaussiansAdded"].get<std::size_t>();
    const std::size_t removed = r["stage2"]["gaussiansRemoved"].get<std::size_t>();
    EXPECT_GT(added, 0u);
    EXPECT_EQ(r["stage2"]["gaussians"].get<std::size_t>(), input + added - removed);
    EXPECT_EQ(readGaussians(dir.file("split") + "/deformed.ply").size(), input + added - removed);
    EXPECT_EQ(readGaussians(dir.file("split") + "/baseline.ply").size(), input);
    // The iterations run in two rounds of 3; the energies of both are in the report.
    EXPECT_EQ(r["stage2"]["energies"].back()["iteration"].get<int>(), 6);
    for (const std::string bad : {"--split sometimes", "--split-stretch 0.5", "--prune-below 1.5", "--split-after -0.1", "--split-offset 0.9"})
        EXPECT_EQ(runCli(base + bad + " -o " + dir.file("bad")), 2) << bad;
}

// With render on, the refine keeps the most stretched region of the samples it warped for Stage
// II: the very region a fresh warp of the rest samples gives (stretched.png needs no second warp).
TEST(DeformPipeline, TheStretchedRegionComesFromTheRefinesWarp)
{
    TempDir dir;
    DeformJobOptions o = smallJob(dir, "bend.json", 3);
    o.render = true;
    o.evaluate = false;
    const DeformSpec spec = loadDeformSpec(o.specPath);
    std::unique_ptr<DeformRest> rest = prepareDeformRest(o, graphOptionsOf(spec, o));
    FrameResult f = poseFrame(*rest, spec, o);
    EXPECT_FALSE(f.stretched);
    refineFrame(*rest, o, f);
    ASSERT_TRUE(f.stretched);
    SampleSet fresh = rest->grid->samples();
    warpSamplesOn(fresh, f.deformation, {rest->device, o.grid.threaded});
    const std::optional<StretchedRegion> expected = mostStretchedRegion(fresh);
    ASSERT_TRUE(expected);
    EXPECT_GT(expected->stretch, 1.05);
    EXPECT_EQ(f.stretched->cell, expected->cell);
    EXPECT_EQ(f.stretched->stretch, expected->stretch);
    EXPECT_EQ(f.stretched->warpedCentre.x, expected->warpedCentre.x);
    EXPECT_EQ(f.stretched->radius, expected->radius);
    // Without render nothing is looked for.
    o.render = false;
    FrameResult g = poseFrame(*rest, spec, o);
    refineFrame(*rest, o, g);
    EXPECT_FALSE(g.stretched);
}
