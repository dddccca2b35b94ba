/// `splatwarp bench render [IN] [--size WxH] [--repeats N] [--device D]`: rasteriser timing.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <string>
#include <tbb/info.h>
#include <vector>

#include "Command.h"
#include "SharedArgs.h"
#include "RenderArgs.h"
#include "core/Progress.h"
#include "io/GaussianIO.h"
#include "ReadArgs.h"
#include "render/Camera.h"
#include "render/RenderDevice.h"
#include "demo/DemoModels.h"

namespace splatwarp::cli {
namespace {

struct BenchRenderArgs {
    std::string input = "stripes", size = "800x800";
    Device device = Device::Auto;
    int repeats = 5;
    bool dropInvalid = false;
};

const CommandRegistrar reg(1010, [](CLI::App& app) {
    auto args = std::make_shared<BenchRenderArgs>();
    CLI::App* sub = benchCommand(app)->add_subcommand(
        "render", "Median time of splat renders (first orbit view; CPU: all cores unless --threads; CUDA: upload, "
                  "render and download of the image)");
    sub->add_option("input", args->input, "Gaussian file, or a sample name (stripes, ring)")->capture_default_str();
    addDropInvalidFlag(sub, args->dropInvalid);
    sub->add_option("--size", args->size, "Image size WIDTHxHEIGHT")->capture_default_str();
    sub->add_option("--repeats", args->repeats, "Timed renders (after one warm-up)")
        ->capture_default_str()
        ->check(positive());
    addDeviceOption(sub, args->device, "to render");
    sub->callback([args] {
        const auto names = demoModelNames();
        const bool sample = !std::filesystem::exists(args->input) &&
                            std::find(names.begin(), names.end(), args->input) != names.end();
        const GaussianCloud cloud = sample ? makeDemoModel(args->input) : readModel(args->input, args->dropInvalid);
        OrbitOptions o;
        o.views = 1;
        parseImageSize(args->size, o.width, o.height);
        const Camera camera = orbitCameras(cloud, o)[0];
        RenderOptions render;
        render.device = resolveDevice(args->device);
        Device device = Device::Cpu;
        renderGaussiansOn(cloud, camera, render, &device); // warm-up: thread pool, page faults, CUDA context
        std::vector<double> ms;
        for (int i = 0; i < args->repeats; ++i) {
            Stopwatch watch;
            renderGaussiansOn(cloud, camera, render);
            ms.push_back(watch.ms());
        }
        std::sort(ms.begin(), ms.end());
        const int threads = globalOptions().threads > 0 ? globalOptions().threads : tbb::info::default_concurrency();
        const std::string where = device == Device::Cuda ? std::string("cuda") : msg("cpu, ", threads, " threads");
        std::printf("render %s: %zu Gaussians (SH %d), %dx%d, %s: median %.1f ms, min %.1f ms (%d runs)\n",
                    args->input.c_str(), cloud.size(), cloud.shDegree, o.width, o.height, where.c_str(),
                    ms[ms.size() / 2], ms.front(), args->repeats);
    });
});

} // namespace
} // namespace splatwarp::cli
