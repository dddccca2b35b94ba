/// `splatwarp deform IN --spec SPEC.json -o OUTDIR --stage1-only`: Stage I (embedded deformation
/// of every Gaussian) -> OUTDIR/baseline.ply and OUTDIR/report.json.
#include <filesystem>

#include "Command.h"
#include "core/AtomicFile.h"
#include "core/Error.h"
#include "core/Progress.h"
#include "deform/DeformReport.h"
#include "deform/StageOne.h"
#include "io/GaussianIO.h"

namespace splatwarp::cli {
namespace {

struct DeformArgs {
    std::string input, spec, outDir;
    bool stage1Only = false;
    GraphOptions graph; // only the values given on the command line are used
};

void runDeform(const DeformArgs& a, const CLI::App& sub)
{
    if (!a.stage1Only)
        throw Error("Stage II is not available yet: run with --stage1-only to write the Stage I baseline");
    Stopwatch clock;
    DeformSpec spec = loadDeformSpec(a.spec);
    if (sub.count("--nodes")) spec.graph.nodes = a.graph.nodes;
    if (sub.count("--k")) spec.graph.k = a.graph.k;
    if (sub.count("--seed")) spec.graph.seed = a.graph.seed;
    ReadReport readReport;
    const GaussianCloud rest = readGaussians(a.input, ReadOptions{}, &readReport);
    const double readMs = clock.ms();
    progress(msg("read ", rest.size(), " Gaussians (SH degree ", rest.shDegree, ") from ", a.input));

    const EdOptions edOptions;
    const Deformation d = solveDeformation(rest, spec, edOptions);
    const StageOneResult s = runStageOne(rest, d);

    clock.reset();
    std::error_code ec;
    std::filesystem::create_directories(a.outDir, ec);
    if (ec) throw IoError(msg(a.outDir, ": cannot create output directory: ", ec.message()));
    const std::string ply = (std::filesystem::path(a.outDir) / "baseline.ply").string();
    writePly(ply, s.deformed);
    nlohmann::json report = stageOneReportJson(d, s, spec.graph, edOptions);
    report["input"] = {{"path", a.input}, {"format", readReport.format}, {"gaussians", rest.size()},
                       {"shDegree", rest.shDegree}};
    report["spec"] = a.spec;
    report["outputs"] = {{"baseline", ply}};
    report["timingsMs"]["read"] = readMs;
    report["timingsMs"]["write"] = clock.ms();
    const std::string reportPath = (std::filesystem::path(a.outDir) / "report.json").string();
    writeFileAtomic(reportPath, report.dump(2) + "\n");
    progress(msg("wrote ", ply, " and ", reportPath));
}

const CommandRegistrar reg(30, [](CLI::App& app) {
    auto args = std::make_shared<DeformArgs>();
    CLI::App* sub = app.add_subcommand("deform", "Deform a 3DGS model with a deformation spec (Stage I: embedded deformation)");
    sub->add_option("input", args->input, "Input model (.ply graphdeco/compressed, .splat)")->required()->check(CLI::ExistingFile);
    sub->add_option("--spec", args->spec, "Deformation spec JSON (see samples/specs/README.md)")->required()->check(CLI::ExistingFile);
    sub->add_option("-o,--output", args->outDir, "Output directory (created): baseline.ply, report.json")->required();
    sub->add_flag("--stage1-only", args->stage1Only, "Stop after Stage I and write the baseline (required until Stage II lands)");
    sub->add_option("--nodes", args->graph.nodes, "Graph node count (overrides the spec's graph.nodes)")->check(CLI::PositiveNumber);
    sub->add_option("--k", args->graph.k, "Nearest nodes per point and edges per node (overrides graph.k)")->check(CLI::Range(1, 64));
    sub->add_option("--seed", args->graph.seed, "Seed of the farthest-point sampling (overrides graph.seed)");
    sub->callback([args, sub] { runDeform(*args, *sub); });
});

} // namespace
} // namespace splatwarp::cli
