/// The `splatwarp` command line: parse, call the library, map errors to exit codes
/// (0 success, 1 bad input or failed job, 2 usage error).
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <new>
#include <tbb/global_control.h>
#include <vector>

#include "Command.h"
#include "core/AtomicFile.h"
#include "core/Error.h"
#include "core/Progress.h"
#include "splatwarp/Version.h"
#include "vdb/VdbLibrary.h"
#ifdef SPLATWARP_WITH_CUDA
#include "kernels/CudaBackends.h"
#endif

namespace splatwarp::cli {

/// The flags of the command that ran that bound its memory, for the out-of-memory message: the
/// counts the user set (`sample --count 4e9`, `deform --nodes 2e9`) first, then its memory flags.
std::string memoryHint(const CLI::App& app)
{
    for (const CLI::App* sub : app.get_subcommands()) {
        std::vector<std::string> flags;
        for (const char* name : {"--count", "--nodes", "--gaussians", "--init-gaussians", "--random-points", "--views",
                                 "--test-views", "--samples-per-voxel", "--eval-points", "--orbit"})
            if (const CLI::Option* given = sub->get_option_no_throw(name); given && given->count() > 0) flags.push_back(name);
        for (const char* name : {"--cells", "--samples-per-cell", "--points", "--size", "--max-memory"})
            if (sub->get_option_no_throw(name)) flags.push_back(name);
        if (!sub->get_subcommands().empty()) return memoryHint(*sub);
        if (flags.empty()) return " (the input is too large for this machine)";
        std::string out;
        for (const std::string& f : flags) out += (out.empty() ? "" : ", ") + f;
        return " (lower or check " + out + ")";
    }
    return "";
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
    for (int i = 1; i < argc; ++i) global.helpAll = global.helpAll || std::string(argv[i]) == "--help-all";
    app.add_flag("-q,--quiet", global.quiet, "No progress lines on stderr");
    app.add_option("--threads", global.threads, "Worker threads for the CPU path (0 = all cores)")
        ->check(cli::nonNegative());

    cli::addCommands(app);
    installSignalCleanup();

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
        std::fprintf(stderr, "splatwarp: usage error: %s\n", printable(e.what()).c_str());
        return 2;
    } catch (const Error& e) {
        std::fprintf(stderr, "splatwarp: error: %s\n", printable(e.what()).c_str());
        return 1;
    } catch (const std::bad_alloc&) {
        std::fprintf(stderr, "splatwarp: error: out of memory%s\n", cli::memoryHint(app).c_str());
        return 1;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "splatwarp: internal error: %s\n", printable(e.what()).c_str());
        return 1;
    }
    // `--json > /dev/full`: what was printed must have reached its destination.
    if (std::fflush(stdout) != 0 || std::ferror(stdout)) {
        std::fprintf(stderr, "splatwarp: error: standard output: write failed: %s\n", std::strerror(errno));
        return 1;
    }
    return 0;
}
