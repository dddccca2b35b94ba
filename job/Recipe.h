#pragma once
/// @file Recipe.h
/// @brief A recipe: the deform pipeline's steps in order, with their settings (`deform --recipe
///        paper|default|FILE.json`). `paper` is the paper's pipeline (Stage I with the polar shape,
///        then Stage II, nothing else); `default` is ours (the steps beyond the paper on). A recipe
///        is data: each step and setting is one row of one table (Recipe.cpp) naming the flag it
///        sets, so a recipe equals a set of flag values, and flags given on the command line win.
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

namespace splatwarp {

struct RecipeStep {
    std::string step;                                        ///< "stage1", "curveSplit", ...
    std::vector<std::pair<std::string, std::string>> settings; ///< key, value (as the flag takes it)
};

struct Recipe {
    std::string name;
    std::vector<RecipeStep> steps;
    bool has(const std::string& step) const;
};

/// @brief The steps a recipe may name, in the order they run.
const std::vector<std::string>& recipeStepNames();

/// @brief "paper" or "default". @throws UsageError for another name.
Recipe builtinRecipe(const std::string& name);

/// @brief {"recipe": NAME, "steps": [{"step": "stage1", "shape": "polar"}, {"step": "stage2"}, ...]}:
///        known steps in run order, each once, stage1 and stage2 present, known settings with
///        string or number values. Pure. @throws InputError naming `path`, the step and the key.
Recipe parseRecipe(const std::string& text, const std::string& path);

/// @brief Whether --recipe's value names a file (it ends in .json), not a built-in recipe.
bool isRecipeFile(const std::string& nameOrPath);

/// @brief A built-in name, else a recipe file read and parsed.
Recipe loadRecipe(const std::string& nameOrPath);

/// @brief The flag values a recipe stands for, in table order: each step's presence flag (on or
///        off) and each setting's flag. Applying them to a command line's defaults gives the recipe.
std::vector<std::pair<std::string, std::string>> recipeFlags(const Recipe& recipe);

/// @brief report.json's "recipe": its name and steps with their settings.
nlohmann::json recipeJson(const Recipe& recipe);

} // namespace splatwarp
