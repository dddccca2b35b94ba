/// The `splatwarp` command line: parse, call the library, map errors to exit codes
/// (0 success, 1 bad input or failed job, 2 usage error).
#include <algorithm>
#include <cstdio>
#include <memory>
#include <tbb/global_control.h>
#include <vector>

#include "Command.h"
#include "core/Error.h"
#include "core/Progress.h"
#include "splatwarp/Version.h"
#include "VdbLibrary.h"
#ifdef SPLATWARP_WITH_CUDA
#include "CudaBackends.h"
#endif

namespace splatwarp::cli {

namespace {
struct Entry {
    int order;
    std::function<void(CLI::App&)> setup;
};
std::vector<Entry>& registry()
{
    static std::vector<Entry> r;
    return r;
}
} // namespace

CommandRegistrar::CommandRegistrar(int order, std::function<void(CLI::App&)> setup)
{
    registry().push_back({order, std::move(setup)});
}

void addCommands(CLI::App& app)
{
    auto entries = registry();
    std::stable_sort(entries.begin(), entries.end(), [](const auto& a, const auto& b) { return a.order < b.order; });
    for (auto& e : entries) e.setup(app);
}

GlobalOptions& globalOptions()
{
    static GlobalOptions g;
    return g;
}

CLI::App* benchCommand(CLI::App& app)
{
    for (CLI::App* sub : app.get_subcommands([](CLI::App* a) { return a->get_name() == "bench"; })) return sub;
    CLI::App* bench = app.add_subcommand("bench", "Benchmarks (times and throughput; results belong in README)");
    bench->require_subcommand(1);
    return bench;
}

} // namespace splatwarp::cli

int main(int argc, char** argv)
{
    using namespace splatwarp;
    CLI::App app{"splatwarp: as-rigid-as-possible deformation of 3D Gaussian Splatting models,\n"
                 "with the radiance field kept consistent (sampled into sparse OpenVDB grids)."};
    app.require_subcommand(1);
#ifdef SPLATWARP_WITH_CUDA
    cuda::registerBackends(); // the core library cannot link the kernels: hand it their entry points
    const char* cuda = "CUDA support: compiled in";
#else
    const char* cuda = "CUDA support: not compiled in";
#endif
    app.set_version_flag("--version", std::string("splatwarp ") + SPLATWARP_VERSION_STRING + "\n" + cuda + "\n" + vdb::libraryVersions());
    cli::GlobalOptions& global = cli::globalOptions();
    app.add_flag("-q,--quiet", global.quiet, "No progress lines on stderr");
    app.add_option("--threads", global.threads, "Worker threads for the CPU path (0 = all cores)")
        ->check(CLI::NonNegativeNumber);

    cli::addCommands(app);

    std::unique_ptr<tbb::global_control> threadLimit;
    app.parse_complete_callback([&] {
        setProgressEnabled(!global.quiet);
        if (global.threads > 0)
            threadLimit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                                std::size_t(global.threads));
    });
    try {
        app.parse(argc, argv);
    } catch (const CLI::CallForHelp& e) {
        return app.exit(e);
    } catch (const CLI::CallForAllHelp& e) {
        return app.exit(e);
    } catch (const CLI::CallForVersion& e) {
        return app.exit(e);
    } catch (const CLI::ParseError& e) {
        app.exit(e);
        return 2;
    } catch (const UsageError& e) {
        std::fprintf(stderr, "splatwarp: usage error: %s\n", e.what());
        return 2;
    } catch (const Error& e) {
        std::fprintf(stderr, "splatwarp: error: %s\n", e.what());
        return 1;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "splatwarp: internal error: %s\n", e.what());
        return 1;
    }
    return 0;
}
