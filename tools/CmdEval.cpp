/// `splatwarp eval --rest REST.ply --deformed DEF.ply --spec SPEC.json`: the fixed judge (job/Judge.h)
/// of any deformed model against the rest model pushed through the spec's deformation; `--lattice`
/// gives the error at a training lattice instead (its cells, cutoff and rest filter).
#include <cstdio>
#include <optional>

#include "Command.h"
#include "GridArgs.h"
#include "SharedArgs.h"
#include "job/FromVdb.h"
#include "job/HeldOutEval.h"
#include "job/Judge.h"
#include "job/MeshJudge.h"
#include "render/Camera.h"
#include "core/AtomicFile.h"
#include "image/ImageIO.h"
#include "mesh/MeshIO.h"
#include "fit/Extinction.h"
#include "core/Error.h"
#include "core/Memory.h"
#include "core/Progress.h"
#include "deform/DeformSpec.h"
#include "io/GaussianIO.h"
#include "ReadArgs.h"

namespace splatwarp::cli {
namespace {

struct EvalArgs {
    std::string rest, deformed, spec;
    std::string volume, model, as = "auto";
    VolumeReadOptions read;
    VolumeJudgeOptions judge;
    bool json = false;
    Device device = Device::Auto;
    SampleGridOptions grid;
    HeldOutOptions heldOut;
    bool dropInvalid = false;
    bool lattice = false;
    std::optional<int> nodes, k;
    std::optional<std::uint32_t> graphSeed;
    std::string mesh, montage;
    MeshReadOptions meshRead;
    MeshJudgeOptions meshJudge;
};

void addMeshOptions(CLI::App* sub, EvalArgs& a)
{
    sub->add_option("--mesh", a.mesh,
                    "Judge by images instead (the paper's judge): this mesh, deformed by the spec's graph built on "
                    "--rest, against --deformed, rendered from --views views over the sphere; PSNR and SSIM per view");
    sub->add_option("--texture", a.meshRead.texture, "With --mesh: texture for materials without one");
    sub->add_flag("--procedural-colour", a.meshRead.proceduralColour, "With --mesh: colour it as from-mesh --procedural-colour did");
    sub->add_option("--views", a.meshJudge.views.views, "With --mesh: views")->capture_default_str()->check(inRange(1, kMaxViews));
    sub->add_option_function<int>("--size", [&a](int s) { a.meshJudge.views.width = a.meshJudge.views.height = s; },
                                  "With --mesh: square view size (default 256)")
        ->check(inRange(11, kMaxImageSide)); // SSIM's 11x11 window
    sub->add_option("--montage", a.montage, "With --mesh: write the worst views (mesh | splats, lowest PSNR first) to this PNG")
        ->check(CLI::Validator(
            [](std::string& path) {
                return lowerExtension(path) == ".png" ? std::string() : "the montage is a PNG: name it *.png, not " + path;
            },
            "PATH.png"));
}

/// `eval --mesh`: PSNR/SSIM of the deformed splats against the deformed mesh.
void evalMesh(const EvalArgs& a, const DeformSpec& spec, const GaussianCloud& rest, const GaussianCloud& deformed)
{
    MeshJudgeOptions options = a.meshJudge;
    options.worst = a.montage.empty() ? 0 : options.worst; // no views kept for a montage nobody asked for
    if (!a.montage.empty() && montageRows(options.worst, options.views.width, options.views.height) == 0)
        throw UsageError(msg("--montage: two views of ", options.views.width, " pixels side by side are wider than ",
                             kMaxImageSide, " (the largest picture our readers read); lower --size"));
    OutputSet outputs({a.mesh, a.rest, a.deformed, a.spec});
    if (!a.montage.empty()) outputs.checkTarget(a.montage);
    const MeshJudgeReport r = judgeAgainstMesh(readMesh(a.mesh, a.meshRead), rest, deformed, spec, options);
    if (!a.montage.empty() && !r.montage.empty()) writePng(a.montage, r.montage);
    outputs.commit();
    if (a.json) {
        nlohmann::json views = nlohmann::json::array();
        for (std::size_t i = 0; i < r.names.size(); ++i) views.push_back({{"name", r.names[i]}, {"psnr", r.psnr[i]}, {"ssim", r.ssim[i]}});
        std::printf("%s\n", nlohmann::json{{"psnr", r.meanPsnr}, {"ssim", r.meanSsim}, {"rigid", r.rigid}, {"views", views}}.dump(2).c_str());
        return;
    }
    std::printf("mesh judge: %zu views of %dx%d%s\nPSNR %.4f dB  SSIM %.6f (means)\n", r.names.size(), a.meshJudge.views.width,
                a.meshJudge.views.height, r.rigid ? " (rigid spec: cameras moved with it)" : "", r.meanPsnr, r.meanSsim);
    for (std::size_t i = 0; i < r.names.size(); ++i) std::printf("  %s  PSNR %.4f  SSIM %.6f\n", r.names[i].c_str(), r.psnr[i], r.ssim[i]);
}

void printReport(const FieldErrorReport& r, bool json)
{
    if (json)
        std::printf("%s\n", fieldErrorJson(r).dump(2).c_str());
    else
        std::printf("%s", judgeText(JudgeReport{r, std::nullopt}).c_str());
}

void addVolumeOptions(CLI::App* sub, EvalArgs& a)
{
    sub->add_option("--volume", a.volume,
                    "Judge --model against this .vdb instead (the from-vdb metric: trilinear values at random "
                    "points of the active voxels and --band voxels around them)");
    sub->add_option("--model", a.model, "With --volume: the splats to judge");
    sub->add_option("--grid", a.read.grid, "With --volume: the FloatGrid (default: density, else the only one)");
    sub->add_option("--color-grid", a.read.colorGrid, "With --volume: the Vec3S colour grid (default color or Cd; none)");
    sub->add_option("--as", a.as, "With --volume: what the model's opacity means (auto, field, extinction; as from-vdb)")
        ->capture_default_str()
        ->check(CLI::IsMember({"auto", "field", "extinction"}));
    sub->add_option("--band", a.judge.band, "With --volume: empty voxels around the active ones that count")
        ->capture_default_str()
        ->check(inRange(0, 16));
}

/// `eval --volume`: the from-vdb held-out error of any splat model against a volume.
void evalVolume(const EvalArgs& a)
{
    if (a.model.empty()) throw UsageError("eval --volume needs --model");
    const Volume volume = readVolume(a.volume, a.read);
    GaussianCloud model = readModel(a.model, a.dropInvalid);
    if (model.shDegree != volume.info().shDegree) model = withShDegree(model, volume.info().shDegree);
    const VolumeMeaning meaning = resolveMeaning(parseVolumeMeaning(a.as), volume);
    const double scale = densityScale(meaning, volume);
    if (meaning == VolumeMeaning::Extinction) opacityToExtinction(model, scale);
    VolumeJudgeOptions judge = a.judge;
    judge.points = a.heldOut.points;
    judge.seed = a.heldOut.seed;
    printReport(judgeModel(makeVolumeJudge(volume, scale, judge), model), a.json);
}

const CommandRegistrar reg(35, [](CLI::App& app) {
    auto a = std::make_shared<EvalArgs>();
    CLI::App* sub = app.add_subcommand(
        "eval", "Field fidelity of a deformed model (the fixed judge): relative L1 error of opacity and SH features at "
                "held-out points of the rest model's active region pushed through the spec's deformation, no low-pass "
                "filter (inside the object and outside it); image PSNR for rigid specs");
    sub->add_option("--rest", a->rest, "Rest (undeformed) model");
    sub->add_option("--deformed", a->deformed, "Deformed model to judge (e.g. baseline.ply or deformed.ply)");
    sub->add_option("--spec", a->spec, "The deformation spec that produced it");
    sub->add_option("--nodes", a->nodes, "Graph node count (overrides the spec's graph.nodes, as deform's --nodes)")->check(positive());
    sub->add_option("--k", a->k, "Nearest nodes per point and edges per node (overrides graph.k, as deform's --k)")->check(inRange(1, 64));
    sub->add_option("--graph-seed", a->graphSeed, "Seed of the graph's node sampling (overrides graph.seed, as deform's --seed)");
    addVolumeOptions(sub, *a);
    addMeshOptions(sub, *a);
    sub->add_option("--points", a->heldOut.points, "Held-out points")->capture_default_str()->check(positive());
    sub->add_option("--seed", a->heldOut.seed, "Seed of the held-out points")->capture_default_str();
    a->grid.samplesPerAxis = kAutoSamplesPerAxis; // --lattice: deform's training lattice by default
    addGridOptions(sub, a->grid);
    addDropInvalidFlag(sub, a->dropInvalid);
    sub->add_flag("--json", a->json, "Print JSON (keys opacity, color, points, inside, outside; imagePsnr for rigid specs)");
    addDeviceOption(sub, a->device, "the rest targets, the point warping and the feature evaluations run (the grid's topology stays on the CPU)");
    sub->add_flag("--lattice", a->lattice,
                  "Judge at a training lattice instead (--cells, --cell-size, --samples-per-cell, --cutoff: its active "
                  "cells and rest filter; what deform's report calls latticeError)");
    sub->callback([a, sub] {
        if (!a->volume.empty()) return evalVolume(*a);
        if (a->rest.empty() || a->deformed.empty() || a->spec.empty())
            throw UsageError("eval needs --rest, --deformed and --spec (or --volume and --model)");
        if (a->mesh.empty())
            for (const char* flag : {"--texture", "--procedural-colour", "--views", "--size", "--montage"})
                if (sub->count(flag) > 0) throw UsageError(msg("eval: ", flag, " is for the image judge: add --mesh MESH"));
        if (!a->lattice)
            for (const char* flag : {"--cells", "--cell-size", "--samples-per-cell", "--cutoff"})
                if (sub->count(flag) > 0)
                    throw UsageError(msg("eval: ", flag, " sets a training lattice, which the judge does not depend on; "
                                         "add --lattice for the error at that lattice"));
        const ResolvedDevice device = resolveDevice(a->device);
        const GaussianCloud rest = readModel(a->rest, a->dropInvalid);
        const GaussianCloud deformed = readModel(a->deformed, a->dropInvalid);
        if (deformed.shDegree != rest.shDegree)
            throw InputError(msg(a->deformed, ": SH degree ", deformed.shDegree, " differs from the rest model's ", rest.shDegree));
        DeformSpec spec = loadDeformSpec(a->spec);
        if (a->nodes) spec.graph.nodes = *a->nodes;
        if (a->k) spec.graph.k = *a->k;
        if (a->graphSeed) spec.graph.seed = *a->graphSeed;
        if (!a->mesh.empty()) return evalMesh(*a, spec, rest, deformed);
        const Deformation deformation = solveDeformation(rest, spec);
        HeldOutOptions heldOut = a->heldOut;
        heldOut.device = device;
        checkEvalPointMemory(heldOut.points, rest.shStride(), true, 0, a->grid.maxMemoryBytes, "--points");
        if (a->lattice) {
            SampleGridOptions gridOptions = a->grid;
            gridOptions.device = device;
            const SampleGrid grid = runStage("sample grid", [&] { return SampleGrid(rest, gridOptions); });
            const HeldOutPoints points = makeHeldOutPoints(grid, deformation, heldOut);
            return printReport(evaluateHeldOut(rest, deformed, points), a->json);
        }
        const Judge judge(rest, prepareJudgeRest(rest, heldOut), deformation);
        const JudgeReport r = judge.judge(deformed);
        if (a->json)
            std::printf("%s\n", judgeJson(r).dump(2).c_str());
        else
            std::printf("%s", judgeText(r).c_str());
    });
});

} // namespace
} // namespace splatwarp::cli
