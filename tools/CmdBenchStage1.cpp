/// `splatwarp bench stage1 [IN] [--spec S] [--device D]`: median times of the Stage I phases.
#include <algorithm>
#include <cstdio>
#include <nlohmann/json.hpp>

#include "Command.h"
#include "SharedArgs.h"
#include "core/Error.h"
#include "core/Progress.h"
#include "deform/StageOneDevice.h"
#include "io/GaussianIO.h"
#include "ReadArgs.h"
#include "demo/DemoModels.h"

namespace splatwarp::cli {
namespace {

struct BenchArgs {
    std::string input;                              // empty: the stripes sample
    bool dropInvalid = false;
    std::string spec = "samples/specs/bend.json";   // relative to the repository root
    int runs = 5;
    bool json = false;
    Device device = Device::Auto;
};

double median(std::vector<double> v)
{
    std::sort(v.begin(), v.end());
    const std::size_t n = v.size();
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

void runBench(const BenchArgs& a)
{
    const GaussianCloud rest = a.input.empty() ? makeDemoModel("stripes") : readModel(a.input, a.dropInvalid);
    const DeformSpec spec = loadDeformSpec(a.spec);
    const bool quiet = !progressEnabled();
    setProgressEnabled(false); // the per-phase lines would swamp the table
    StageOneOptions options;
    options.device = resolveDevice(a.device);
    std::vector<double> graphMs, weightsMs, uploadMs, solveMs, updateMs, stepMs, previewMs;
    Deformation d;
    StageOneResult s;
    for (int r = 0; r < a.runs; ++r) {
        Stopwatch t;
        const DeformationGraph graph = DeformationGraph::build(rest, spec.graph);
        graphMs.push_back(t.ms());
        t.reset();
        const StageOneRig rig = prepareStageOne(rest, graph, options);
        weightsMs.push_back(t.ms());
        t.reset();
        // The rest model and rig go to the device once per model; a step uploads only the
        // node transforms.
        StageOneUpdater updater(rest, rig, graph, options);
        uploadMs.push_back(t.ms());
        t.reset();
        d = solveDeformation(graph, rest, spec);
        solveMs.push_back(t.ms());
        const Stopwatch u;
        s = updater.apply(d.transforms, d.nodeMoving);
        updateMs.push_back(u.ms());
        stepMs.push_back(t.ms());
        // The editor's drag preview (float, no SH) of the same transforms, into a reused cloud.
        GaussianCloud preview = withShDegree(rest, 0);
        for (int warm = 0; warm < 2; ++warm) {
            const Stopwatch p;
            applyStageOnePreview(rest, rig, graph, d.transforms, d.nodeMoving, options, preview);
            if (warm) previewMs.push_back(p.ms());
        }
    }
    setProgressEnabled(!quiet);
    const std::string name = a.input.empty() ? std::string("stripes (sample)") : a.input;
    nlohmann::json j = {{"model", name}, {"spec", a.spec}, {"gaussians", rest.size()}, {"shDegree", rest.shDegree},
                        {"nodes", d.graph.nodeCount()}, {"k", d.graph.k()}, {"moving", s.movingCount},
                        {"solverIterations", d.report.solver.iterations}, {"runs", a.runs}, {"device", deviceName(s.device)},
                        {"medianMs", {{"graph", median(graphMs)}, {"weights", median(weightsMs)}, {"upload", median(uploadMs)},
                                      {"solve", median(solveMs)}, {"update", median(updateMs)}, {"preview", median(previewMs)},
                                      {"step", median(stepMs)}, {"precompute", median(graphMs) + median(weightsMs)}}}};
    if (a.json) {
        std::printf("%s\n", j.dump(2).c_str());
        return;
    }
    std::printf("Stage I benchmark: %s, %zu Gaussians (SH %d), %zu nodes, k %d, %zu moving, %d GN iterations, update on %s\n",
                name.c_str(), rest.size(), rest.shDegree, d.graph.nodeCount(), d.graph.k(), s.movingCount,
                d.report.solver.iterations, deviceName(s.device));
    std::printf("%-34s %10s\n", "phase (median of runs)", "ms");
    const auto& m = j["medianMs"];
    std::printf("%-34s %10.2f\n", "graph build (FPS + edges)", m["graph"].get<double>());
    std::printf("%-34s %10.2f\n", "skin weights (7 points/Gaussian)", m["weights"].get<double>());
    std::printf("%-34s %10.2f\n", "ED solve", m["solve"].get<double>());
    std::printf("%-34s %10.2f\n", "per-Gaussian update", m["update"].get<double>());
    std::printf("%-34s %10.2f\n", "editor preview update (CPU, float)", m["preview"].get<double>());
    std::printf("%-34s %10.2f\n", "step = solve + update", m["step"].get<double>());
    std::printf("%-34s %10.2f\n", "precompute = graph + weights", m["precompute"].get<double>());
}

const CommandRegistrar reg(1010, [](CLI::App& app) {
    auto args = std::make_shared<BenchArgs>();
    CLI::App* sub = benchCommand(app)->add_subcommand("stage1", "Time Stage I: graph build, skin weights, ED solve, per-Gaussian update");
    sub->add_option("input", args->input, "Model to deform (default: the stripes sample)")->check(CLI::ExistingFile);
    addDropInvalidFlag(sub, args->dropInvalid);
    sub->add_option("--spec", args->spec, "Deformation spec (default: samples/specs/bend.json, from the repository root)")
        ->capture_default_str();
    sub->add_option("--runs", args->runs, "Runs per phase; the median is reported")->check(inRange(1, 1000))->capture_default_str();
    sub->add_flag("--json", args->json, "Print JSON instead of a table");
    addDeviceOption(sub, args->device,
                    "the per-Gaussian update runs (the rest model and rig are uploaded once per run, outside the step)");
    sub->callback([args] { runBench(*args); });
});

} // namespace
} // namespace splatwarp::cli
