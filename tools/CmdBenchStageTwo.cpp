/// `splatwarp bench stage2`: Stage II time per iteration and pair throughput on the stripes
/// sample. The sample set is built here without VDB (bench only): cells of edge
/// (largest extent)/64 holding a Gaussian centre, dilated by one cell, n^3 samples each;
/// targets = features of the model turned 10 degrees about z (a rigid "deformation").
#include <cmath>
#include <map>
#include <set>
#include <tuple>

#include "Command.h"
#include "SharedArgs.h"
#include "core/Error.h"
#include "core/Progress.h"
#include "field/FeatureField.h"
#include "samples/SampleModels.h"
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
    Vec3f lo, hi;
    centreBounds(rest, lo, hi);
    SampleSet s;
    s.shDegree = rest.shDegree;
    s.samplesPerAxis = n;
    s.cellSize = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z}) / 64.0f;
    s.spacing = s.cellSize / float(n);
    std::set<std::tuple<int, int, int>> cells;
    for (std::size_t i = 0; i < rest.size(); ++i) {
        const Vec3f p = rest.mean(i);
        const int c[3] = {int(std::floor(p.x / s.cellSize)), int(std::floor(p.y / s.cellSize)),
                          int(std::floor(p.z / s.cellSize))};
        for (int dx = -1; dx <= 1; ++dx)
            for (int dy = -1; dy <= 1; ++dy)
                for (int dz = -1; dz <= 1; ++dz) cells.insert({c[0] + dx, c[1] + dy, c[2] + dz});
    }
    std::map<std::tuple<int, int, int>, std::int32_t> index;
    std::int32_t k = 0;
    for (const auto& [cx, cy, cz] : cells) {
        index[{cx, cy, cz}] = k;
        for (int a = 0; a < n; ++a)
            for (int b = 0; b < n; ++b)
                for (int d = 0; d < n; ++d) {
                    s.restPositions.insert(s.restPositions.end(), {s.cellSize * float(cx) + s.spacing * (float(a) + 0.5f),
                                                                   s.cellSize * float(cy) + s.spacing * (float(b) + 0.5f),
                                                                   s.cellSize * float(cz) + s.spacing * (float(d) + 0.5f)});
                    s.sampleCell.push_back(k);
                }
        s.cellGradient.insert(s.cellGradient.end(), {1, 0, 0, 0, 1, 0, 0, 0, 1});
        s.cellSkip.push_back(0);
        ++k;
    }
    gaussianCell.resize(rest.size());
    for (std::size_t i = 0; i < rest.size(); ++i) {
        const Vec3f p = rest.mean(i);
        gaussianCell[i] = index[{int(std::floor(p.x / s.cellSize)), int(std::floor(p.y / s.cellSize)),
                                 int(std::floor(p.z / s.cellSize))}];
    }
    s.warpedPositions = s.restPositions;
    FeatureOptions fo;
    fo.cutoff = o.cutoff;
    fo.filterVariance = o.lowPassFilter ? o.lambdaLpf * s.spacing * s.spacing : 0.0f;
    evaluateSampleTargets(target, s, fo);
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
        const GaussianCloud rest = makeSample("stripes");
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
