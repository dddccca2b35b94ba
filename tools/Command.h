#pragma once
/// @file Command.h
/// @brief Subcommand registry: each tools/Cmd*.cpp registers itself with a static
///        CommandRegistrar, so adding a command never touches main.cpp.
#include <CLI/CLI.hpp>
#include <functional>
#include <string>
#include <vector>

namespace splatwarp::cli {

/// @brief Adds a subcommand to the app; `order` fixes its place in --help.
struct CommandRegistrar {
    CommandRegistrar(int order, std::function<void(CLI::App&)> setup);
};

/// @brief Options every computing command shares (set by main before callbacks run).
struct GlobalOptions {
    bool quiet = false;
    int threads = 0;      ///< 0 = all cores
    bool helpAll = false; ///< `--help-all` on the command line: expert flags are listed too (main sets it first)
};
GlobalOptions& globalOptions();

/// @brief The flags a user of a command touches stay in its --help; every other option of it
///        (positionals aside) moves to the expert level, listed by `--help-all` only (it still works).
void splitHelpLevels(CLI::App* sub, const std::vector<std::string>& userFlags);

/// @brief Add every registered subcommand to app, in --help order (main, and `batch` for each job).
void addCommands(CLI::App& app);

/// @brief Checks every command's options get (main calls it once all commands are registered):
///        each float option refuses NaN/Inf and each text option an empty value (usage errors).
void addCommonChecks(CLI::App& app);

/// @brief A float flag that must lie strictly between lo and hi (e.g. a field of view in (0, 180)).
CLI::Validator openInterval(double lo, double hi);
/// @brief Number checks with readable messages, used instead of CLI::Range / PositiveNumber /
///        NonNegativeNumber (whose messages print 309-digit bounds).
CLI::Validator inRange(double lo, double hi);
CLI::Validator positive();
CLI::Validator nonNegative();
/// @brief `word` as a whole number in [lo, hi] (decimal, nothing after it), or nothing.
bool parseWholeNumber(const std::string& word, long lo, long hi, long& n);
/// @brief An `auto|N` flag: "auto" or a whole number in [lo, hi] (usage error: "must be auto or a
///        whole number from lo to hi, not '...'").
CLI::Validator autoOrWholeNumber(long lo, long hi, const std::string& label);

/// @brief The `bench` parent command (created on first use): each benchmark registers
///        `bench NAME` with `benchCommand(app)->add_subcommand(...)` from a CommandRegistrar
///        of order >= 1000.
CLI::App* benchCommand(CLI::App& app);

} // namespace splatwarp::cli
