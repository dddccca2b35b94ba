#include "job/Recipe.h"

#include <algorithm>

#include "job/Sequence.h"
#include "core/AtomicFile.h"
#include "core/Error.h"
#include "io/JsonText.h"

namespace splatwarp {

namespace {

using json = nlohmann::json;

/// A step in run order, and the flag that turns it on or off ("": a step every recipe has). A
/// setting of the same flag (curveShift's share, keep's mode) comes after and wins.
struct StepRow {
    const char* step;
    const char* flag;
    const char* on;
    const char* off;
};
const StepRow kSteps[] = {
    {"stage1", "", "", ""},
    {"curveSplit", "--curve-split", "auto", "off"},
    {"validatedSplit", "--validated-split", "auto", "off"},
    {"curveShift", "--curve-shift", "auto", "0"},
    {"split", "--split", "auto", "off"},
    {"stage2", "", "", ""},
    {"keep", "--keep", "validated", "fit"},
};

/// A step's setting and the flag it sets.
struct SettingRow {
    const char* step;
    const char* key;
    const char* flag;
};
const SettingRow kSettings[] = {
    {"stage1", "shape", "--stage1-shape"},        {"stage1", "endpointSigmas", "--endpoint-sigmas"},
    {"curveSplit", "max", "--curve-split-max"},   {"curveSplit", "rounds", "--curve-split-rounds"},
    {"curveSplit", "fan", "--curve-split-fan"},   {"curveSplit", "prune", "--curve-split-prune"},
    {"curveShift", "share", "--curve-shift"},
    {"split", "stretch", "--split-stretch"},      {"split", "after", "--split-after"},
    {"split", "offset", "--split-offset"},        {"stage2", "iterations", "--iterations"},
    {"stage2", "boundaryWeight", "--boundary-weight"}, {"stage2", "stallTolerance", "--stall-tolerance"},
    {"stage2", "cells", "--cells"},               {"stage2", "samplesPerCell", "--samples-per-cell"},
    {"stage2", "pruneBelow", "--prune-below"},    {"keep", "mode", "--keep"},
    {"keep", "validationStop", "--validation-stop"},
};

const SettingRow* settingRow(const std::string& step, const std::string& key)
{
    for (const SettingRow& r : kSettings)
        if (step == r.step && key == r.key) return &r;
    return nullptr;
}

std::string valueText(const json& v, const std::string& where)
{
    if (v.is_string()) return v.get<std::string>();
    if (v.is_number()) return v.dump();
    throw InputError(msg(where, ": must be a string or a number"));
}

RecipeStep parseStep(const json& s, const std::string& where)
{
    if (!s.is_object() || !s.contains("step") || !s["step"].is_string())
        throw InputError(msg(where, ": needs \"step\" (one of ", [] {
                             std::string l;
                             for (const std::string& n : recipeStepNames()) l += (l.empty() ? "" : ", ") + n;
                             return l;
                         }(), ")"));
    RecipeStep step{s["step"].get<std::string>(), {}};
    const auto& names = recipeStepNames();
    if (std::find(names.begin(), names.end(), step.step) == names.end())
        throw InputError(msg(where, ": unknown step \"", step.step, "\""));
    for (const auto& [key, value] : s.items()) {
        if (key == "step") continue;
        if (!settingRow(step.step, key)) throw InputError(msg(where, " (", step.step, "): unknown setting \"", key, "\""));
        step.settings.emplace_back(key, valueText(value, msg(where, " (", step.step, ") \"", key, "\"")));
    }
    return step;
}

} // namespace

bool Recipe::has(const std::string& step) const
{
    return std::any_of(steps.begin(), steps.end(), [&](const RecipeStep& s) { return s.step == step; });
}

const std::vector<std::string>& recipeStepNames()
{
    static const std::vector<std::string> names = [] {
        std::vector<std::string> n;
        for (const StepRow& r : kSteps) n.push_back(r.step);
        return n;
    }();
    return names;
}

Recipe builtinRecipe(const std::string& name)
{
    if (name == "paper")
        return {"paper", {{"stage1", {{"shape", "polar"}}}, {"stage2", {{"iterations", "100"}, {"boundaryWeight", "99"}}}}};
    if (name == "default")
        return {"default", {{"stage1", {}}, {"curveSplit", {}}, {"validatedSplit", {}}, {"curveShift", {}}, {"stage2", {}}, {"keep", {}}}};
    throw UsageError(msg("--recipe must be paper, default or a recipe file (.json), not '", name, "'"));
}

Recipe parseRecipe(const std::string& text, const std::string& path)
{
    json root;
    try {
        root = parseJson(text);
    } catch (const json::exception& e) {
        throw InputError(msg(path, ": invalid JSON: ", e.what()));
    }
    if (!root.is_object() || !root.contains("steps") || !root["steps"].is_array())
        throw InputError(msg(path, ": needs \"steps\": an array of {\"step\": NAME, settings...}"));
    Recipe r;
    r.name = root.contains("recipe") && root["recipe"].is_string() ? root["recipe"].get<std::string>() : path;
    const auto& names = recipeStepNames();
    std::size_t last = 0;
    for (std::size_t i = 0; i < root["steps"].size(); ++i) {
        RecipeStep s = parseStep(root["steps"][i], msg(path, ": step ", i));
        const std::size_t at = std::size_t(std::find(names.begin(), names.end(), s.step) - names.begin());
        if (!r.steps.empty() && at <= last)
            throw InputError(msg(path, ": step ", i, " (", s.step, ") is out of order or repeated; the order is stage1, curveSplit, "
                                 "validatedSplit, curveShift, split, stage2, keep"));
        last = at;
        r.steps.push_back(std::move(s));
    }
    for (const char* required : {"stage1", "stage2"})
        if (!r.has(required)) throw InputError(msg(path, ": a recipe needs the step \"", required, "\" (deform --stage1-only stops after Stage I)"));
    return r;
}

bool isRecipeFile(const std::string& nameOrPath)
{
    return nameOrPath.size() >= 5 && nameOrPath.compare(nameOrPath.size() - 5, 5, ".json") == 0;
}

Recipe loadRecipe(const std::string& nameOrPath)
{
    if (!isRecipeFile(nameOrPath)) return builtinRecipe(nameOrPath);
    return parseRecipe(readWholeFile(nameOrPath, "recipe"), nameOrPath);
}

std::vector<std::pair<std::string, std::string>> recipeFlags(const Recipe& recipe)
{
    std::vector<std::pair<std::string, std::string>> flags;
    for (const StepRow& row : kSteps) {
        const auto it = std::find_if(recipe.steps.begin(), recipe.steps.end(), [&](const RecipeStep& s) { return s.step == row.step; });
        if (*row.flag) flags.emplace_back(row.flag, it == recipe.steps.end() ? row.off : row.on);
        if (it == recipe.steps.end()) continue;
        for (const auto& [key, value] : it->settings) flags.emplace_back(settingRow(row.step, key)->flag, value);
    }
    return flags;
}

json recipeJson(const Recipe& recipe)
{
    json steps = json::array();
    for (const RecipeStep& s : recipe.steps) {
        json step = {{"step", s.step}};
        for (const auto& [key, value] : s.settings) step[key] = value;
        steps.push_back(step);
    }
    return {{"name", recipe.name}, {"steps", steps}};
}

} // namespace splatwarp
