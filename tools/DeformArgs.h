#pragma once
/// @file DeformArgs.h
/// @brief The Stage I / Stage II / evaluation flags shared by `deform` and `animate` (one definition).
#include <cstdint>
#include <algorithm>
#include <cstdlib>
#include <memory>
#include <string>

#include "Command.h"
#include "job/DeformPipeline.h"
#include "GridArgs.h"
#include "job/Recipe.h"
#include "ReadArgs.h"
#include "SharedArgs.h"

namespace splatwarp::cli {

struct DeformArgs {
    DeformJobOptions job;
    int nodes = 0, k = 0;
    std::uint32_t seed = 0;
    bool noLpf = false, noEval = false;
    std::string fineCells = "off";
    std::string stage1Shape = "affine";
    std::string split = "off";
    std::string curveSplit = "auto", validatedSplit = "auto", keep = "validated", curveShift = "auto";
    std::string recipe = "default";
    std::string maxGaussians;
    float fineBelow = 4.0f;
};

/// @brief --fine-cells and --fine-below (deform and animate; to-vdb keeps the uniform lattice).
inline void addFineCellOptions(CLI::App* sub, DeformArgs& args)
{
    sub->add_option("--fine-cells", args.fineCells,
                    "Finer Stage II samples where the Gaussians are small: auto gives a cell (2n)^3 samples when the "
                    "median largest scale of the Gaussians centred in it is below --fine-below x the sample spacing h/n "
                    "(its Gaussians' rest and Stage II filter then use the spacing h/2n); off: n^3 in every cell")
        ->capture_default_str()
        ->check(CLI::IsMember({"auto", "off"}));
    sub->add_option("--fine-below", args.fineBelow,
                    "With --fine-cells auto: the median largest Gaussian scale, in units of the spacing h/n, below which "
                    "a cell is fine")
        ->capture_default_str()
        ->check(inRange(1e-3, 100.0));
    sub->add_flag("--fine-neighbours", args.job.grid.fineNeighbours,
                  "With --fine-cells auto: also refine the 26 neighbours of each fine cell");
}

/// @brief The steps around Stage II that add or choose Gaussians: --curve-split, --validated-split,
///        --max-gaussians, --curve-split-max/-rounds/-fan, --curve-shift, --keep.
inline void addSplitStepOptions(CLI::App* sub, DeformArgs& args)
{
    sub->add_option("--curve-split", args.curveSplit,
                    "auto: before Stage II, split each Gaussian that the deformation bends more than one affine map can "
                    "follow into three along the bent axis, in the rest pose, and move the children with Stage I again "
                    "(most gain first, see --curve-split-max); off: Stage II starts from the Stage I model")
        ->capture_default_str()
        ->check(CLI::IsMember({"auto", "off"}));
    sub->add_option("--validated-split", args.validatedSplit,
                    "auto: after the curve split, split each moving Gaussian still as Stage I left it in three along "
                    "the one of its axes that helps most, where the exact drop of the validation score (the judge's rule, "
                    "other seeds) says it pays, largest drops first (needs --keep validated or regions; shares "
                    "--curve-split-max); off: no such split")
        ->capture_default_str()
        ->check(CLI::IsMember({"auto", "off"}));
    sub->add_option("--max-gaussians", args.maxGaussians,
                    "The most Gaussians the output may hold: N, or a factor of the input's count such as 1.5x (1x: "
                    "no growth); the curve split, the validated split and Stage II's split spend it in that order "
                    "(default: none; the curve split's own share then bounds the splits before Stage II)")
        ->check([](const std::string& text) {
            GaussianBudget unused;
            return parseGaussianBudget(text, unused);
        });
    sub->add_option("--curve-split-max", args.job.curve.maxAdded,
                    "At most this many Gaussians added by the curve split and the validated split together, as a share "
                    "of the model's")
        ->capture_default_str()
        ->check(inRange(0.0, 16.0));
    sub->add_option("--curve-split-rounds", args.job.curve.rounds,
                    "With --curve-split auto: children still bent are split again, up to this many rounds in all")
        ->capture_default_str()
        ->check(inRange(1, 8));
    sub->add_option("--curve-split-fan", args.job.curve.fanAbove,
                    "With --curve-split auto: a Gaussian bent by more than this many of its sigmas is fanned into many "
                    "thin children at once (three rounds of halving could not straighten it); with --keep validated the "
                    "split is made with fans and without and the validation points keep the better; 0: never fan")
        ->capture_default_str()
        ->check(inRange(0.0, 1000.0));
    sub->add_option("--curve-shift", args.curveShift,
                    "With --keep validated: one more candidate of the keep, the start with each moving Gaussian's mean "
                    "moved by this share of the deformation's second-order offset along its axes (where its mass goes "
                    "on a curve); auto: the share of 0.25, 0.5, 0.75, 1 the validation points judge best; 0: none")
        ->capture_default_str()
        ->check(CLI::Validator(
            [](std::string& word) {
                if (word == "auto") return std::string();
                char* end = nullptr;
                const double v = std::strtod(word.c_str(), &end);
                return end != word.c_str() && *end == '\0' && v >= 0.0 && v <= 2.0
                           ? std::string()
                           : "must be auto or a number from 0 to 2, not '" + word + "'";
            },
            "auto|SHARE"));
    sub->add_option("--keep", args.keep,
                    "validated: after Stage II keep its start, the curve-shifted start (--curve-shift), its fit or a "
                    "mix of them (per region of a 16-cell lattice), whichever is judged best on validation points (the "
                    "judge's rule, other seeds), then let each moving Gaussian, heaviest first, take the candidate's "
                    "version of it that lowers the validation score; regions: the region mix only; fit: always keep the fit")
        ->capture_default_str()
        ->check(CLI::IsMember({"validated", "regions", "fit"}));
}

/// @brief --split, --split-stretch, --split-after, --split-offset, --prune-below (Stage II in rounds,
///        src/stage2/Densify.h), and between them (for --help's order) addSplitStepOptions().
inline void addDensifyOptions(CLI::App* sub, DeformArgs& args)
{
    DensifyJobOptions& d = args.job.densify;
    sub->add_option("--split", args.split,
                    "auto: split each moving Gaussian whose rest cell's deformation gradient F has its largest singular "
                    "value above --split-stretch into two along its longest axis (same mass, mean, covariance and colour), "
                    "between two Stage II rounds; off: one round")
        ->capture_default_str()
        ->check(CLI::IsMember({"auto", "off"}));
    sub->add_option("--split-stretch", d.splitStretch,
                    "With --split auto: the largest singular value of a cell's F above which its Gaussians split")
        ->capture_default_str()
        ->check(inRange(1.0, 100.0));
    sub->add_option("--split-after", d.splitAfter,
                    "With --split auto: share of the Stage II iterations run before the split (0: split first)")
        ->capture_default_str()
        ->check(inRange(0.0, 1.0));
    sub->add_option("--split-offset", d.splitOffset,
                    "With --split auto: the children sit at the mean +- this x sigma along the longest axis (their "
                    "sigma there is sqrt(1 - offset^2) x the parent's)")
        ->capture_default_str()
        ->check(inRange(0.05, double(kMaxSplitOffset)));
    addSplitStepOptions(sub, args);
    sub->add_option("--prune-below", d.pruneBelow,
                    "Remove the moving Gaussians whose opacity Stage II leaves below this (before the split and at the "
                    "end; 0: keep every Gaussian)")
        ->capture_default_str()
        ->check(inRange(0.0, 1.0));
}

/// @brief Every flag of a deform run except the input, --spec, -o, --vdb and --render.
inline void addDeformOptions(CLI::App* sub, DeformArgs& args)
{
    DeformJobOptions& job = args.job;
    sub->add_option("--recipe", args.recipe,
                    "The pipeline: default (ours: the curve split, validated split, curve shift and validated keep "
                    "around Stage II), paper (the paper's: Stage I with the polar shape, then Stage II with its "
                    "boundary weight 99, nothing else) or a recipe file (.json, docs/recipes.md); flags given "
                    "beside it win")
        ->capture_default_str();
    sub->add_flag("--stage1-only", job.stage1Only,
                  "Stop after Stage I (write the Stage I model only; deform also removes deformed.ply, field.vdb and "
                  "compare.png of an earlier run in the output directory, so no stale result sits beside them)");
    addDropInvalidFlag(sub, job.dropInvalid);
    sub->add_option("--nodes", args.nodes, "Graph node count (overrides the spec's graph.nodes)")->check(positive());
    sub->add_option("--k", args.k, "Nearest nodes per point and edges per node (overrides graph.k)")->check(inRange(1, 64));
    sub->add_option("--seed", args.seed, "Seed of the farthest-point sampling (overrides graph.seed)");
    sub->add_option("--stage1-shape", args.stage1Shape,
                    "How Stage I shapes a moving Gaussian from the affine map M fitted to its skinned endpoints: affine "
                    "(covariance M Sigma M^T, so shear and a flat Gaussian's turning normal follow) or polar (the paper: "
                    "M's rotation, each axis scaled by M's stretch along it)")
        ->capture_default_str()
        ->check(CLI::IsMember({"affine", "polar"}));
    sub->add_option("--endpoint-sigmas", job.stage1.endpointSigmas,
                    "Stage I fits M to the skinned endpoints at +-this many standard deviations along each Gaussian "
                    "axis (the paper: 2)")
        ->capture_default_str()
        ->check(CLI::Range(0.1, 5.0));
    job.grid.samplesPerAxis = kAutoSamplesPerAxis;
    addGridOptions(sub, job.grid);
    addFineCellOptions(sub, args);
    addDensifyOptions(sub, args);
    addIterationsOption(sub, job.stage2);
    sub->add_option("--boundary-weight", job.stage2.boundaryWeight,
                    "lambda2: extra weight of |O* - O| where the target is empty (keeps Gaussians out of empty space)")
        ->capture_default_str()
        ->check(nonNegative());
    sub->add_option("--stall-tolerance", job.stage2.stallTolerance,
                    "Stop Stage II early when its energy fell by less than this fraction over the last 10 iterations "
                    "(0: run every iteration; a step that raises the energy is always undone, and 6 such in a row end the run)")
        ->capture_default_str()
        ->check(inRange(0.0, 1.0));
    addMaxMeanStepOption(sub, job.stage2);
    sub->add_flag("--no-lpf", args.noLpf, "Turn off the adaptive anisotropic low-pass filter");
    addCoverageOptions(sub, job.stage2);
    sub->add_option("--eval-every", job.evalEvery, "Record the held-out field error every K Stage II iterations in the report")
        ->check(nonNegative());
    sub->add_option("--eval-points", job.heldOut.points, "Held-out points for the field errors")->capture_default_str()->check(positive());
    sub->add_flag("--no-eval", args.noEval, "Skip the held-out field errors");
    addDeviceOption(sub, job.device,
                    "the computing stages run (Stage I update, field targets, sample and held-out warping, held-out "
                    "evaluation, Stage II, --render)");
}

/// @brief Set the recipe's flag values on every flag not given on the command line, through the
///        flags' own conversion and checks (job/Recipe.h).
inline Recipe applyRecipe(CLI::App* sub, const std::string& nameOrPath)
{
    const Recipe recipe = loadRecipe(nameOrPath);
    std::vector<std::string> given;
    for (const auto& [flag, value] : recipeFlags(recipe))
        if (sub->count(flag) > 0) given.push_back(flag);
    for (const auto& [flag, value] : recipeFlags(recipe)) {
        if (std::find(given.begin(), given.end(), flag) != given.end()) continue;
        CLI::Option* option = sub->get_option(flag);
        try {
            option->clear();
            option->add_result(value);
            option->run_callback();
        } catch (const CLI::Error& e) {
            throw InputError(msg("recipe ", recipe.name, ": ", flag, " ", value, ": ", e.what()));
        }
    }
    return recipe;
}

/// @brief The job options once parsed (the recipe first, then overrides only for the flags given).
inline DeformJobOptions deformJobOptions(DeformArgs& args, CLI::App* sub)
{
    args.job.recipe = recipeJson(applyRecipe(sub, args.recipe));
    DeformJobOptions job = args.job;
    if (sub->count("--nodes")) job.nodes = args.nodes;
    if (sub->count("--k")) job.k = args.k;
    if (sub->count("--seed")) job.seed = args.seed;
    job.stage2.lowPassFilter = !args.noLpf;
    job.grid.fineBelow = args.fineCells == "auto" ? args.fineBelow : 0.0f;
    job.stage1.shape = args.stage1Shape == "polar" ? StageOneShape::Polar : StageOneShape::Affine;
    job.evaluate = !args.noEval;
    job.densify.split = args.split == "auto";
    job.curveSplit = args.curveSplit == "auto";
    job.keepValidated = args.keep != "fit";
    job.validatedSplit = args.validatedSplit == "auto";
    job.keepPerGaussian = args.keep == "validated";
    if (args.curveShift != "auto") job.curveShift = std::strtod(args.curveShift.c_str(), nullptr);
    if (!args.maxGaussians.empty()) {
        if (sub->count("--curve-split-max")) throw UsageError("--curve-split-max and --max-gaussians: give one budget");
        parseGaussianBudget(args.maxGaussians, job.maxGaussians.emplace());
    }
    return job;
}

} // namespace splatwarp::cli
