/// The CLI's subcommand registry and its flag checks (Command.h): shared by the `splatwarp`
/// executable (main.cpp) and the Python module (python/), whose keyword arguments are these flags.
#include "Command.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <memory>
#include <vector>

#include "core/Error.h"

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

} // namespace splatwarp::cli
