/// `splatwarp bench features`: throughput of the radial-feature evaluation on the stripes sample.
#include <random>

#include "Command.h"
#include "SharedArgs.h"
#include "core/Error.h"
#include "core/Progress.h"
#include "field/FeatureDevice.h"
#include "field/FeatureField.h"
#include "demo/DemoModels.h"

namespace splatwarp::cli {
namespace {

struct BenchFeatureArgs {
    std::size_t points = 1000000;
    int degree = -1;
    bool serial = false;
    Device device = Device::Auto;
};

const CommandRegistrar reg(1010, [](CLI::App& app) {
    auto args = std::make_shared<BenchFeatureArgs>();
    CLI::App* sub = benchCommand(app)->add_subcommand("features", "Feature evaluation F, O on the stripes sample (CPU or GPU)");
    sub->add_option("--points", args->points, "Points: random Gaussian centres plus N(0, 0.03) noise")->capture_default_str();
    sub->add_option("--degree", args->degree, "Truncate the sample's SH to this degree (-1: keep, 1)")->capture_default_str();
    sub->add_flag("--serial", args->serial, "Single thread (pairs per second per core)");
    addDeviceOption(sub, args->device, "the evaluation runs (the timing includes preparation and binning)");
    sub->callback([args] {
        GaussianCloud g = makeDemoModel("stripes");
        if (args->degree >= 0 && args->degree < g.shDegree) {
            GaussianCloud t;
            t.resize(g.size(), args->degree);
            t.means = g.means; t.rotations = g.rotations; t.logScales = g.logScales; t.opacities = g.opacities;
            for (std::size_t i = 0; i < g.size(); ++i)
                for (int s = 0; s < t.shStride(); ++s) t.shOf(i)[s] = g.shOf(i)[s];
            g = std::move(t);
        }
        // Points near the surface, where the sample lattice's work is: a random centre + noise.
        std::mt19937 rng(1);
        std::uniform_int_distribution<std::size_t> pick(0, g.size() - 1);
        std::normal_distribution<float> noise(0.0f, 0.03f);
        std::vector<float> pts(3 * args->points);
        for (std::size_t p = 0; p < args->points; ++p) {
            const Vec3f c = g.mean(pick(rng));
            for (int k = 0; k < 3; ++k) pts[3 * p + std::size_t(k)] = c[k] + noise(rng);
        }
        FeatureOptions opt;
        opt.threaded = !args->serial;
        opt.device = resolveDevice(args->device);
        std::vector<float> f(args->points * std::size_t(g.shStride())), o(args->points);
        FeatureStats stats;
        Stopwatch sw;
        const Device used = evaluateFeaturesOn(g, pts.data(), args->points, opt, f.data(), o.data(), &stats);
        const double ms = sw.ms();
        std::printf("features on %s: %zu Gaussians SH%d, %zu points, %.1f ms, pairs tested %llu (%.1f M/s), "
                    "contributing %llu, bin cell %.4g, bin entries %llu\n",
                    deviceName(used), g.size(), g.shDegree, args->points, ms, (unsigned long long)stats.pairsTested,
                    double(stats.pairsTested) / ms * 1e-3, (unsigned long long)stats.pairsContributing,
                    double(stats.binCellSize), (unsigned long long)stats.binEntries);
    });
});

} // namespace
} // namespace splatwarp::cli
