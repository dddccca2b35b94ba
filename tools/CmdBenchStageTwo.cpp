/// `splatwarp bench stage2`: Stage II time per iteration and pair throughput on the stripes
/// sample. The samples are the rest model's SampleGrid (64 cells, n^3 samples per cell, every
/// cell used); targets = features of the model turned 10 degrees about z (a rigid "deformation").
#include <cmath>

#include "Command.h"
#include "vdb/SampleGrid.h"
#include "SharedArgs.h"
#include "core/Error.h"
#include "core/Progress.h"
#include "field/FeatureField.h"
#include "demo/DemoModels.h"
#include "field/RigidMotion.h"
#include "stage2/StageTwoDevice.h"

namespace splatwarp::cli {
namespace {

struct BenchStageTwoArgs {
    int samplesPerAxis = 2;
    Device device = Device::Auto;
    StageTwoOptions options;
};

SampleSet benchSamples(const GaussianCloud& rest, const GaussianCloud& target, int n, const StageTwoOptions& o,
                       std::vector<std::int32_t>& gaussianCell)
{
    SampleGridOptions go;
    go.samplesPerAxis = n;
    go.cutoff = o.cutoff;
    go.lambdaLpf = o.lowPassFilter ? o.lambdaLpf : 0.0f;
    go.threaded = o.threaded;
    go.device = o.device; // the grid's targets and the turned model's below run where Stage II runs
    const SampleGrid grid(rest, go);
    gaussianCell = grid.gaussianCell();
    SampleSet s = grid.samples();
    evaluateSampleTargets(target, s, grid.targetOptions());
    // The grid's skip flags describe the rest targets, not the moved model's: use every cell.
    s.cellSkip.assign(s.cellCount(), 0);
    return s;
}

const CommandRegistrar reg(1020, [](CLI::App& app) {
    auto args = std::make_shared<BenchStageTwoArgs>();
    args->options.iterations = 10;
    CLI::App* sub = benchCommand(app)->add_subcommand("stage2", "Stage II optimiser on the stripes sample");
    sub->add_option("--iterations", args->options.iterations, "Adam iterations")->capture_default_str();
    sub->add_option("--samples-per-axis", args->samplesPerAxis, "n: samples per cell axis")->capture_default_str();
    addDeviceOption(sub, args->device, "Stage II runs");
    sub->add_flag("--serial", [args](std::int64_t) { args->options.threaded = false; }, "Single thread");
    sub->callback([args] {
        args->options.device = resolveDevice(args->device);
        const GaussianCloud rest = makeDemoModel("stripes");
        const double angle = 10.0 * M_PI / 180.0;
        Mat3d rot = Mat3d::identity();
        rot.m[0][0] = rot.m[1][1] = std::cos(angle);
        rot.m[0][1] = -std::sin(angle);
        rot.m[1][0] = std::sin(angle);
        const GaussianCloud target = rigidlyMoved(rest, rot, Vec3d(0, 0, 0));
        Stopwatch sw;
        std::vector<std::int32_t> cells;
        const SampleSet s = benchSamples(rest, target, args->samplesPerAxis, args->options, cells);
        const double msSamples = sw.ms();
        GaussianCloud cloud = rest;
        std::vector<std::uint8_t> moving(rest.size(), 1);
        const StageTwoReport r = runStageTwo(cloud, s, moving, cells, args->options);
        std::uint64_t pairs = 0;
        for (std::uint64_t p : r.pairsPerIteration) pairs += p;
        const double it = std::max(1, args->options.iterations);
        std::printf("stage2 (%s): %zu Gaussians SH%d, %zu samples (built in %.0f ms), %d iterations\n",
                    deviceName(r.device), rest.size(), rest.shDegree, r.samplesUsed, msSamples, args->options.iterations);
        std::printf("  energy %.6g -> %.6g (held iterate %d, %d steps rejected)\n", r.energies.front().total,
                    r.bestEnergy, r.bestIteration, r.rejectedSteps);
        std::printf("  per iteration: %.1f ms total; coverage %.1f, forward %.1f, backward %.1f, update %.1f ms; "
                    "setup %.1f ms once\n",
                    (r.msTotal - r.msSetup) / it, r.msCoverage / it, r.msForward / it, r.msBackward / it,
                    r.msUpdate / it, r.msSetup);
        std::printf("  counted pairs/iteration %.3g, candidate pairs %llu, %.1f M counted pairs/s (forward+backward)\n",
                    double(pairs) / it, (unsigned long long)r.coveragePairs,
                    double(pairs) / (r.msForward + r.msBackward) * 1e-3);
        if (r.device == Device::Cuda)
            std::printf("  peak GPU memory of the run's buffers: %.1f MiB\n", double(r.gpuPeakBytes) / (1024.0 * 1024.0));
    });
});

} // namespace
} // namespace splatwarp::cli
