#pragma once
/// @file DeformArgs.h
/// @brief The flags of a deform run, made from its one settings table (job/DeformSettings.h) for
///        `deform`, `animate`, `edit`, batch jobs and the Python module, plus --recipe.
#include <map>
#include <string>
#include <vector>

#include "Command.h"
#include "core/Error.h"
#include "job/DeformSettings.h"
#include "job/Recipe.h"

namespace splatwarp::cli {

struct DeformArgs {
    DeformJobOptions job = deformDefaults(); ///< the command's own options (input, spec, output) go here
    std::string recipe = "default";
    std::map<std::string, std::string> given; ///< the table's flags given on the command line, as text
};

/// @brief --recipe and every row of the settings table, in the table's order; a value is checked as
///        it is parsed and applied by deformJobOptions().
inline void addDeformOptions(CLI::App* sub, DeformArgs& args)
{
    sub->add_option("--recipe", args.recipe,
                    "The pipeline: default (ours: the curve split, validated split, curve shift and validated keep "
                    "around Stage II), paper (the paper's: Stage I with the polar shape, then Stage II with its "
                    "boundary weight 99, nothing else) or a recipe file (.json, docs/recipes.md); flags given "
                    "beside it win")
        ->capture_default_str();
    static const DeformJobOptions defaults = deformDefaults();
    for (const Setting& s : deformSettings()) {
        const std::string flag = s.flag;
        if (!s.takesValue()) {
            sub->add_flag_function(flag, [&args, flag](std::int64_t) { args.given[flag] = "true"; }, s.help);
            continue;
        }
        auto check = [&s](std::string& text) {
            DeformJobOptions scratch = defaults;
            try {
                s.set(scratch, text);
            } catch (const UsageError& e) { // CLI11 puts "--flag: " before it
                const std::string what = e.what();
                return what.rfind(s.flag + " ", 0) == 0 ? what.substr(s.flag.size() + 1) : what;
            }
            return std::string();
        };
        CLI::Option* option =
            sub->add_option_function<std::string>(flag, [&args, flag](const std::string& text) { args.given[flag] = text; }, s.help)
                ->type_name(s.typeName)
                ->check(CLI::Validator(check, ""));
        if (!s.text(defaults).empty()) option->default_str(s.text(defaults));
    }
}

/// @brief The flags a user touches (deform's --help; --help-all lists the rest): the table's user
///        rows and the command's own.
inline std::vector<std::string> userFlags(std::vector<std::string> own)
{
    own.push_back("--recipe");
    for (const Setting& s : deformSettings())
        if (s.level == SettingLevel::User) own.push_back(s.flag);
    return own;
}

/// @brief The job options once parsed: each row in the table's order takes its value as given on
///        the command line, else the recipe's (job/Recipe.h), else keeps its default.
inline DeformJobOptions deformJobOptions(DeformArgs& args)
{
    const Recipe recipe = loadRecipe(args.recipe);
    const std::vector<std::pair<std::string, std::string>> fromRecipe = recipeFlags(recipe);
    DeformJobOptions job = args.job;
    job.recipe = recipeJson(recipe);
    if (isRecipeFile(args.recipe)) job.recipePath = args.recipe;
    for (const Setting& s : deformSettings()) {
        const auto given = args.given.find(s.flag);
        if (given != args.given.end()) {
            s.set(job, given->second);
            continue;
        }
        for (const auto& [flag, value] : fromRecipe) { // in the recipe's order: a step's setting after its presence
            if (flag != s.flag) continue;
            try {
                s.set(job, value);
            } catch (const UsageError& e) {
                throw InputError(msg("recipe ", recipe.name, ": ", flag, " ", value, ": ", e.what()));
            }
        }
    }
    if (job.maxGaussians && args.given.count("--curve-split-max") && !mergesToBudget(job))
        throw UsageError("--curve-split-max and --max-gaussians (" + job.maxGaussians->text() +
                         "): without the budget's merge the splits spend the budget itself; give one (--max-gaussians none)");
    return job;
}

} // namespace splatwarp::cli
