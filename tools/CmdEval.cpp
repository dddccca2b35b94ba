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
};

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
    sub->add_option("--points", a->heldOut.points, "Held-out points")->capture_default_str()->check(positive());
    sub->add_option("--seed", a->heldOut.seed, "Seed of the held-out points")->capture_default_str();
    a->grid.samplesPerAxis = kAutoSamplesPerAxis; // --lattice: deform's training lattice by default
    addGridOptions(sub, a->grid);
    addDropInvalidFlag(sub, a->dropInvalid);
    sub->add_flag("--json", a->json, "Print JSON (keys opacity, color, points, inside, outside; image_psnr for rigid specs)");
    addDeviceOption(sub, a->device, "the rest targets, the point warping and the feature evaluations run (the grid's topology stays on the CPU)");
    sub->add_flag("--lattice", a->lattice,
                  "Judge at a training lattice instead (--cells, --cell-size, --samples-per-cell, --cutoff: its active "
                  "cells and rest filter; what deform's report calls lattice_error)");
    sub->callback([a, sub] {
        if (!a->volume.empty()) return evalVolume(*a);
        if (a->rest.empty() || a->deformed.empty() || a->spec.empty())
            throw UsageError("eval needs --rest, --deformed and --spec (or --volume and --model)");
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
        const Deformation deformation = solveDeformation(rest, spec);
        HeldOutOptions heldOut = a->heldOut;
        heldOut.device = device;
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
