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
    addCommonChecks(app);
}

GlobalOptions& globalOptions()
{
    static GlobalOptions g;
    return g;
}

namespace {
/// Float flags: CLI11 parses "nan", "inf" and "1e999" into values every range check lets through.
const CLI::Validator kFinite(
    [](std::string& text) {
        double v = 0.0;
        if (CLI::detail::lexical_cast(text, v) && !std::isfinite(v)) return "must be a finite number, got '" + text + "'";
        return std::string();
    },
    "FINITE");
const CLI::Validator kNonEmpty([](std::string& text) { return text.empty() ? std::string("must not be empty") : std::string(); },
                               "");
} // namespace

namespace {
/// A number check with a readable message (CLI11's Range prints std::to_string: 309 digits for
/// DBL_MAX, "0.000000" for 1e-8).
CLI::Validator numberCheck(std::function<bool(double)> ok, const std::string& what, const std::string& label)
{
    return CLI::Validator(
        [ok, what](std::string& text) {
            double v = 0.0;
            if (!CLI::detail::lexical_cast(text, v) || !ok(v)) return msg("must be ", what, ", got '", text, "'");
            return std::string();
        },
        label);
}
} // namespace

CLI::Validator openInterval(double lo, double hi)
{
    return numberCheck([lo, hi](double v) { return v > lo && v < hi; }, msg("strictly between ", lo, " and ", hi),
                       msg("in (", lo, ", ", hi, ")"));
}

CLI::Validator inRange(double lo, double hi)
{
    return numberCheck([lo, hi](double v) { return v >= lo && v <= hi; }, msg("in [", lo, ", ", hi, "]"),
                       msg("in [", lo, ", ", hi, "]"));
}

CLI::Validator positive() { return numberCheck([](double v) { return v > 0; }, "positive", "POSITIVE"); }

CLI::Validator nonNegative() { return numberCheck([](double v) { return v >= 0; }, "non-negative", "NONNEGATIVE"); }

bool parseWholeNumber(const std::string& word, long lo, long hi, long& n)
{
    errno = 0;
    char* end = nullptr;
    n = std::strtol(word.c_str(), &end, 10);
    return !word.empty() && errno == 0 && end && *end == '\0' && n >= lo && n <= hi;
}

CLI::Validator autoOrWholeNumber(long lo, long hi, const std::string& label)
{
    return CLI::Validator(
        [lo, hi](std::string& word) {
            long n = 0;
            return word == "auto" || parseWholeNumber(word, lo, hi, n)
                       ? std::string()
                       : msg("must be auto or a whole number from ", lo, " to ", hi, ", not '", word, "'");
        },
        label);
}

void addCommonChecks(CLI::App& app)
{
    for (CLI::Option* option : app.get_options()) {
        const std::string type = option->get_type_name();
        if (type.rfind("FLOAT", 0) == 0) option->check(kFinite);
        if (type.rfind("TEXT", 0) == 0) option->check(kNonEmpty);
    }
    for (CLI::App* sub : app.get_subcommands([](CLI::App*) { return true; })) addCommonChecks(*sub);
}

namespace {
constexpr const char* kExpertGroup = "Expert options";

/// --help leaves the expert group out, --help-all shows it. (CLI11's hidden group "" would also
/// drop the flag's name from its error messages.)
class LevelFormatter : public CLI::Formatter {
public:
    std::string make_group(std::string group, bool is_positional, std::vector<const CLI::Option*> opts) const override
    {
        if (group == kExpertGroup && !globalOptions().helpAll) return "";
        return CLI::Formatter::make_group(std::move(group), is_positional, std::move(opts));
    }
};
} // namespace

void splitHelpLevels(CLI::App* sub, const std::vector<std::string>& userFlags)
{
    sub->set_help_all_flag("--help-all", "Print every flag, the expert ones too, and exit");
    sub->formatter(std::make_shared<LevelFormatter>());
    for (CLI::Option* option : sub->get_options()) {
        if (option->get_positional() || option == sub->get_help_ptr() || option == sub->get_help_all_ptr()) continue;
        const bool user = std::any_of(userFlags.begin(), userFlags.end(), [&](const std::string& f) { return option->check_name(f); });
        if (!user) option->group(kExpertGroup);
    }
}

CLI::App* benchCommand(CLI::App& app)
{
    for (CLI::App* sub : app.get_subcommands([](CLI::App* a) { return a->get_name() == "bench"; })) return sub;
    CLI::App* bench = app.add_subcommand("bench", "Benchmarks (times and throughput; results: docs/benchmarks.md)");
    bench->require_subcommand(1);
    return bench;
}

/// The flags of the command that ran that bound its memory, for the out-of-memory message.
std::string memoryHint(const CLI::App& app)
{
    for (const CLI::App* sub : app.get_subcommands()) {
        std::vector<std::string> flags;
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
