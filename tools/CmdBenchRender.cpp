/// `splatwarp bench render [IN] [--size WxH] [--repeats N]`: CPU rasteriser timing.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <tbb/info.h>
#include <vector>

#include "Command.h"
#include "RenderArgs.h"
#include "core/Progress.h"
#include "io/GaussianIO.h"
#include "render/Camera.h"
#include "render/Rasterizer.h"
#include "samples/SampleModels.h"

namespace splatwarp::cli {
namespace {

struct BenchRenderArgs {
    std::string input = "stripes", size = "800x800";
    int repeats = 5;
};

const CommandRegistrar reg(1010, [](CLI::App& app) {
    auto args = std::make_shared<BenchRenderArgs>();
    CLI::App* sub = benchCommand(app)->add_subcommand(
        "render", "Median time of CPU splat renders (first orbit view, all cores unless --threads)");
    sub->add_option("input", args->input, "Gaussian file, or a sample name (stripes, ring)")->capture_default_str();
    sub->add_option("--size", args->size, "Image size WIDTHxHEIGHT")->capture_default_str();
    sub->add_option("--repeats", args->repeats, "Timed renders (after one warm-up)")
        ->capture_default_str()
        ->check(CLI::PositiveNumber);
    sub->callback([args] {
        const auto names = sampleNames();
        const bool sample = !std::filesystem::exists(args->input) &&
                            std::find(names.begin(), names.end(), args->input) != names.end();
        const GaussianCloud cloud = sample ? makeSample(args->input) : readGaussians(args->input);
        OrbitOptions o;
        o.views = 1;
        parseImageSize(args->size, o.width, o.height);
        const Camera camera = orbitCameras(cloud, o)[0];
        renderGaussians(cloud, camera); // warm-up: thread pool, page faults
        std::vector<double> ms;
        for (int i = 0; i < args->repeats; ++i) {
            Stopwatch watch;
            renderGaussians(cloud, camera);
            ms.push_back(watch.ms());
        }
        std::sort(ms.begin(), ms.end());
        const int threads = globalOptions().threads > 0 ? globalOptions().threads : tbb::info::default_concurrency();
        std::printf("render %s: %zu Gaussians (SH %d), %dx%d, %d threads: median %.1f ms, min %.1f ms (%d runs)\n",
                    args->input.c_str(), cloud.size(), cloud.shDegree, o.width, o.height, threads,
                    ms[ms.size() / 2], ms.front(), args->repeats);
    });
});

} // namespace
} // namespace splatwarp::cli
