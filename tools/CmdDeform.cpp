/// `splatwarp deform IN --spec SPEC.json -o OUTDIR`: Stage I (embedded deformation) and Stage II
/// (fit to the warped radiance field) -> baseline.ply, deformed.ply, report.json [, field.vdb, compare.png].
#include <cstdio>

#include "Command.h"
#include "DeformPipeline.h"
#include "GridArgs.h"
#include "core/Device.h"
#include "core/Error.h"

namespace splatwarp::cli {
namespace {

struct DeformArgs {
    DeformJobOptions job;
    int nodes = 0, k = 0;
    std::uint32_t seed = 0;
    bool noLpf = false, noEval = false;
    std::string device = "auto";
};

const CommandRegistrar reg(30, [](CLI::App& app) {
    auto args = std::make_shared<DeformArgs>();
    DeformJobOptions& job = args->job;
    CLI::App* sub = app.add_subcommand(
        "deform", "Deform a 3DGS model with a deformation spec: Stage I (embedded deformation) then Stage II "
                  "(fit the Gaussians to the warped radiance field)");
    sub->add_option("input", job.input, "Input model (.ply graphdeco/compressed, .splat, .spz)")->required();
    sub->add_option("--spec", job.specPath, "Deformation spec JSON (see samples/specs/README.md)")->required();
    sub->add_option("-o,--output", job.outDir, "Output directory (created): baseline.ply, deformed.ply, report.json")->required();
    sub->add_flag("--stage1-only", job.stage1Only, "Stop after Stage I: write baseline.ply and report.json only");
    sub->add_option("--nodes", args->nodes, "Graph node count (overrides the spec's graph.nodes)")->check(CLI::PositiveNumber);
    sub->add_option("--k", args->k, "Nearest nodes per point and edges per node (overrides graph.k)")->check(CLI::Range(1, 64));
    sub->add_option("--seed", args->seed, "Seed of the farthest-point sampling (overrides graph.seed)");
    addGridOptions(sub, job.grid);
    sub->add_option("--iterations", job.stage2.iterations, "Stage II Adam iterations")->capture_default_str()->check(CLI::NonNegativeNumber);
    sub->add_option("--boundary-weight", job.stage2.boundaryWeight,
                    "lambda2: extra weight of |O* - O| where the target is empty (keeps Gaussians out of empty space)")
        ->capture_default_str()
        ->check(CLI::NonNegativeNumber);
    sub->add_flag("--no-lpf", args->noLpf, "Turn off the adaptive anisotropic low-pass filter");
    sub->add_option("--rebuild-every", job.stage2.rebuildEvery, "Rebuild the Gaussian-sample coverage every K iterations")
        ->capture_default_str()
        ->check(CLI::PositiveNumber);
    sub->add_option("--eval-every", job.evalEvery, "Record the held-out field error every K Stage II iterations in the report")
        ->check(CLI::NonNegativeNumber);
    sub->add_option("--eval-points", job.heldOut.points, "Held-out points for the field errors")->capture_default_str()->check(CLI::PositiveNumber);
    sub->add_flag("--no-eval", args->noEval, "Skip the held-out field errors");
    sub->add_option("--device", args->device, "Where the computing stages run (Stage I update, field targets, sample and held-out warping, held-out evaluation, Stage II, --render): auto (CUDA when compiled in and a GPU is present; out of GPU memory falls back to the CPU), cpu, cuda")
        ->capture_default_str()
        ->check(CLI::IsMember({"auto", "cpu", "cuda"}));
    sub->add_flag("--vdb", job.writeVdb, "Also write field.vdb: the Stage II model's sampled field (as `to-vdb`)");
    sub->add_flag("--render", job.render, "Also write compare.png: rest | Stage I | Stage II from a few orbit views");
    sub->callback([args, sub] {
        DeformJobOptions job = args->job;
        if (sub->count("--nodes")) job.nodes = args->nodes;
        if (sub->count("--k")) job.k = args->k;
        if (sub->count("--seed")) job.seed = args->seed;
        job.stage2.lowPassFilter = !args->noLpf;
        job.evaluate = !args->noEval;
        job.device = parseDevice(args->device);
        if (job.render && job.stage1Only) throw UsageError("--render needs Stage II (drop --stage1-only)");
        const nlohmann::json report = runDeformJob(job);
        // A short summary on stdout (progress lines go to stderr).
        std::printf("outputs:");
        for (const auto& [name, path] : report["outputs"].items()) std::printf(" %s", path.get<std::string>().c_str());
        std::printf(" %s/report.json\n", job.outDir.c_str());
        if (report.contains("stage2") && report["stage2"].contains("field_error")) {
            const auto& e1 = report["stage1"]["field_error"];
            const auto& e2 = report["stage2"]["field_error"];
            std::printf("held-out field error (opacity, color): Stage I %.4g, %.4g -> Stage II %.4g, %.4g\n",
                        e1["opacity"].get<double>(), e1["color"].get<double>(), e2["opacity"].get<double>(),
                        e2["color"].get<double>());
        }
    });
});

} // namespace
} // namespace splatwarp::cli
