/// `splatwarp bench to-vdb [IN]`: sample grid build + rest targets + .vdb export throughput.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <sys/resource.h>
#include <tbb/global_control.h>
#include <tbb/info.h>
#include <tbb/task_arena.h>

#include "Command.h"
#include "SharedArgs.h"
#include "vdb/SampleGrid.h"
#include "vdb/VdbExport.h"
#include "core/Error.h"
#include "core/Progress.h"
#include "io/GaussianIO.h"
#include "ReadArgs.h"
#include "demo/DemoModels.h"

namespace splatwarp::cli {
namespace {

struct BenchToVdbArgs {
    std::string input;
    bool dropInvalid = false;
    SampleGridOptions grid;
    std::vector<int> degrees{0, 2};
    Device device = Device::Auto;
};

/// Peak resident set size of the process so far, MiB (Linux reports ru_maxrss in KiB).
double peakRssMiB()
{
    rusage u{};
    getrusage(RUSAGE_SELF, &u);
    return double(u.ru_maxrss) / 1024.0;
}

const CommandRegistrar reg(1040, [](CLI::App& app) {
    auto args = std::make_shared<BenchToVdbArgs>();
    CLI::App* sub = benchCommand(app)->add_subcommand(
        "to-vdb", "Sample grid (topology, rest targets) and .vdb export: samples/s, pair evaluations/s, peak memory");
    sub->add_option("input", args->input, "Input Gaussians (default: the procedural stripes sample)");
    addDropInvalidFlag(sub, args->dropInvalid);
    sub->add_option("--cells", args->grid.cells, "Cells along the model's largest extent")->capture_default_str()->check(positive());
    sub->add_option("--samples-per-cell", args->grid.samplesPerAxis, "Samples per cell along each axis")
        ->capture_default_str()
        ->check(inRange(2, 16));
    sub->add_option("--degrees", args->degrees, "SH degrees to run at (bands dropped or zero-padded)")
        ->capture_default_str()
        ->check(inRange(0, 3));
    addDeviceOption(sub, args->device, "the rest targets run (topology and export stay on the CPU)");
    sub->callback([args] {
        args->grid.device = resolveDevice(args->device);
        const GaussianCloud source = args->input.empty() ? makeDemoModel("stripes") : readModel(args->input, args->dropInvalid);
        const std::string label = args->input.empty() ? std::string("stripes") : args->input;
        // The threads that run (--threads limits them through a global control, not the arena).
        const int threads = int(std::min<std::size_t>(std::size_t(tbb::this_task_arena::max_concurrency()),
                                                      tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism)));
        const std::string tmp = (std::filesystem::temp_directory_path() / "splatwarp-bench-to-vdb.vdb").string();
        for (const int degree : args->degrees) {
            const GaussianCloud cloud = withShDegree(source, degree);
            Stopwatch total;
            const SampleGrid grid(cloud, args->grid);
            Stopwatch io;
            writeSampleGridVdb(tmp, grid, {});
            const double exportMs = io.ms(), totalMs = total.ms();
            const std::uintmax_t bytes = std::filesystem::file_size(tmp);
            std::filesystem::remove(tmp);
            const SampleGridStats& s = grid.stats();
            const double featureS = s.featuresMs * 1e-3;
            std::printf("to-vdb %s: %zu Gaussians SH%d, %d threads, targets on %s, %zu cells (%zu skipped), %zu samples\n",
                        label.c_str(), cloud.size(), degree, threads, deviceName(s.device), s.cells, s.skippedCells,
                        s.samples);
            std::printf("  topology %.0f ms, features %.0f ms, export %.0f ms (%.1f MiB), total %.0f ms\n", s.topologyMs,
                        s.featuresMs, exportMs, double(bytes) / (1 << 20), totalMs);
            std::printf("  samples/s %.3g (features) %.3g (end to end); pairs tested %.3g (%.3g/s, %.3g/s/core), "
                        "contributing %.3g; peak RSS %.0f MiB\n",
                        double(s.samples) / featureS, double(s.samples) / (totalMs * 1e-3), double(s.pairsTested),
                        double(s.pairsTested) / featureS, double(s.pairsTested) / featureS / threads,
                        double(s.pairsContributing), peakRssMiB());
        }
    });
});

} // namespace
} // namespace splatwarp::cli
