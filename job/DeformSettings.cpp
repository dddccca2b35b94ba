#include "job/DeformSettings.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <iomanip>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <type_traits>

#include "core/Error.h"
#include "core/Memory.h"

namespace splatwarp {
namespace {

using json = nlohmann::json;
using Level = SettingLevel;
constexpr Level User = Level::User, Expert = Level::Expert;

/// A field of the options a row reads and writes.
template <class T>
using Field = T& (*)(DeformJobOptions&);

template <class T>
const T& valueOf(Field<T> field, const DeformJobOptions& o)
{
    return field(const_cast<DeformJobOptions&>(o)); // read only
}

/// The shortest text that reads back to v (to a float's precision when `single`); 1000000, not 1e+06.
std::string numberText(double v, bool single = false)
{
    if (v == std::floor(v) && std::fabs(v) < 1e15) return std::to_string(std::int64_t(v));
    for (int digits = 6;; ++digits) {
        std::ostringstream s;
        s << std::setprecision(digits) << v;
        const double back = std::strtod(s.str().c_str(), nullptr);
        if (digits == 17 || (single ? float(back) == float(v) : back == v)) return s.str();
    }
}

/// The values a number may take: [lo, hi], lo excluded when open.
struct Bounds {
    double lo, hi;
    bool open = false;
    std::string text() const
    {
        const std::string upTo = hi == HUGE_VAL ? "" : " and <= " + numberText(hi);
        if (open) return "a number > " + numberText(lo) + upTo;
        if (hi == HUGE_VAL) return "a number >= " + numberText(lo);
        return "a number from " + numberText(lo) + " to " + numberText(hi);
    }
};
const Bounds kPositive{0, HUGE_VAL, true}, kNonNegative{0, HUGE_VAL};

/// @throws UsageError unless `text` is a number within `b` (a whole one when `whole`); the message
///        names the flag and, for a flag that also takes a word, that word (`alternative`: "auto").
double parseNumber(const std::string& flag, const std::string& text, const Bounds& b, bool whole,
                   const std::string& alternative = "")
{
    char* end = nullptr;
    const double v = std::strtod(text.c_str(), &end);
    const bool ok = !text.empty() && end && *end == '\0' && std::isfinite(v) && (b.open ? v > b.lo : v >= b.lo) &&
                    v <= b.hi && (!whole || v == std::floor(v));
    if (!ok)
        throw UsageError(msg(flag, " must be ", alternative.empty() ? "" : alternative + " or ", whole ? "a whole " : "",
                             whole ? b.text().substr(2) : b.text(), ", not '", text, "'"));
    return v;
}

/// `b` within what T holds (a whole number past an int's range is refused, not wrapped; a float
/// past FLT_MAX, not made infinite).
template <class T>
Bounds within(Bounds b)
{
    b.hi = std::min(b.hi, double(std::numeric_limits<T>::max()));
    return b;
}

/// A setting that is one number of the options.
template <class T>
Setting number(const char* flag, const char* key, Level level, std::string help, Field<T> field, Bounds bounds,
               bool showDefault = true)
{
    constexpr bool whole = std::is_integral_v<T>;
    Setting s{flag, whole ? "INT" : "FLOAT", level, std::move(help), {}, {}, {}};
    s.set = [=](DeformJobOptions& o, const std::string& text) {
        field(o) = T(parseNumber(flag, text, within<T>(bounds), whole));
    };
    s.write = [=](const DeformJobOptions& o, json& out) { out[key] = valueOf(field, o); };
    s.text = [=](const DeformJobOptions& o) {
        return showDefault ? numberText(double(valueOf(field, o)), std::is_same_v<T, float>) : std::string();
    };
    return s;
}

/// A graph setting that overrides the spec's when given (-1 in the record: the spec's).
template <class T>
Setting graphOverride(const char* flag, const char* key, std::string help,
                      std::optional<T>& (*field)(DeformJobOptions&), Bounds bounds)
{
    Setting s{flag, "INT", Expert, std::move(help), {}, {}, {}};
    s.set = [=](DeformJobOptions& o, const std::string& text) {
        field(o) = T(parseNumber(flag, text, within<T>(bounds), true));
    };
    s.write = [=](const DeformJobOptions& o, json& out) {
        const std::optional<T>& v = field(const_cast<DeformJobOptions&>(o));
        out[key] = v ? std::int64_t(*v) : std::int64_t(-1);
    };
    s.text = [](const DeformJobOptions&) { return std::string(); };
    return s;
}

/// A switch: given, the field takes `given`; the record holds the field.
Setting toggle(const char* flag, const char* key, Level level, std::string help, Field<bool> field, bool given = true)
{
    Setting s{flag, "", level, std::move(help), {}, {}, {}};
    s.set = [=](DeformJobOptions& o, const std::string&) { field(o) = given; };
    s.write = [=](const DeformJobOptions& o, json& out) {
        if (*key) out[key] = valueOf(field, o);
    };
    s.text = [](const DeformJobOptions&) { return std::string(); };
    return s;
}

/// A setting with words for values: `set` gets a word of `words` (checked here).
Setting word(const char* flag, const std::vector<std::string>& words, Level level, std::string help,
             std::function<void(DeformJobOptions&, const std::string&)> set,
             std::function<std::string(const DeformJobOptions&)> text,
             std::function<void(const DeformJobOptions&, json&)> write)
{
    std::string names;
    for (const std::string& w : words) names += (names.empty() ? "" : "|") + w;
    Setting s{flag, names, level, std::move(help), {}, std::move(write), std::move(text)};
    s.set = [=](DeformJobOptions& o, const std::string& value) {
        if (std::find(words.begin(), words.end(), value) == words.end())
            throw UsageError(msg(flag, " must be one of ", names, ", not '", value, "'"));
        set(o, value);
    };
    return s;
}

/// `--iterations auto|N`: auto sets the cap and the stall stop (StageTwoOptions::setAutoIterations()).
void setIterations(StageTwoOptions& stageTwo, const std::string& word)
{
    if (word == "auto") {
        stageTwo.setAutoIterations();
        return;
    }
    stageTwo.iterations = int(parseNumber("--iterations", word, {0, 1000000}, true, "auto"));
    stageTwo.scheduleIterations = 0;
}

/// A word setting whose record is its word under `key`.
Setting recordedWord(const char* flag, const char* key, const std::vector<std::string>& words, std::string help,
                     std::function<void(DeformJobOptions&, const std::string&)> set,
                     std::function<std::string(const DeformJobOptions&)> text)
{
    return word(flag, words, Expert, std::move(help), std::move(set), text,
                [=](const DeformJobOptions& o, json& out) { out[key] = text(o); });
}

/// auto|off settings that turn a step on (auto) or off.
Setting onOff(const char* flag, const char* key, std::string help, Field<bool> field, bool writeWhenOn = true)
{
    return word(
        flag, {"auto", "off"}, Expert, std::move(help), [=](DeformJobOptions& o, const std::string& w) { field(o) = w == "auto"; },
        [=](const DeformJobOptions& o) { return valueOf(field, o) ? "auto" : "off"; },
        [=](const DeformJobOptions& o, json& out) {
            if (writeWhenOn || !valueOf(field, o)) out[key] = valueOf(field, o);
        });
}

std::vector<Setting> stageOneSettings()
{
    return {
        toggle("--stage1-only", "stage1Only", User,
               "Stop after Stage I (write the Stage I model only; deform also removes deformed.ply, field.vdb and "
               "compare.png of an earlier run in the output directory, so no stale result sits beside them)",
               [](DeformJobOptions& o) -> bool& { return o.stage1Only; }),
        toggle("--drop-invalid", "dropInvalid", Expert,
               "Drop unusable Gaussians (NaN/Inf values, scales whose exp() overflows, zero quaternions) "
               "and say how many (default: refuse the file)", [](DeformJobOptions& o) -> bool& { return o.dropInvalid; }),
        graphOverride<int>("--nodes", "nodes", "Graph node count (overrides the spec's graph.nodes)",
                      [](DeformJobOptions& o) -> std::optional<int>& { return o.nodes; }, kPositive),
        graphOverride<int>("--k", "k", "Nearest nodes per point and edges per node (overrides graph.k)",
                      [](DeformJobOptions& o) -> std::optional<int>& { return o.k; }, {1, 64}),
        graphOverride<std::uint32_t>("--seed", "seed", "Seed of the farthest-point sampling (overrides graph.seed)",
                                [](DeformJobOptions& o) -> std::optional<std::uint32_t>& { return o.seed; }, {0, 4294967295.0}),
        recordedWord("--stage1-shape", "stage1Shape", {"affine", "polar"},
             "How Stage I shapes a moving Gaussian from the affine map M fitted to its skinned endpoints: affine "
             "(covariance M Sigma M^T, so shear and a flat Gaussian's turning normal follow) or polar (the paper: "
             "M's rotation, each axis scaled by M's stretch along it)",
             [](DeformJobOptions& o, const std::string& w) {
                 o.stage1.shape = w == "polar" ? StageOneShape::Polar : StageOneShape::Affine;
             },
             [](const DeformJobOptions& o) { return o.stage1.shape == StageOneShape::Polar ? "polar" : "affine"; }),
        number<double>("--endpoint-sigmas", "endpointSigmas", Expert,
                       "Stage I fits M to the skinned endpoints at +-this many standard deviations along each Gaussian "
                       "axis (the paper: 2)",
                       [](DeformJobOptions& o) -> double& { return o.stage1.endpointSigmas; }, {0.1, 5.0}),
    };
}

std::vector<Setting> gridSettings()
{
    return {
        number<int>("--cells", "cells", User, "Cells along the model's largest extent (ignored with --cell-size)",
                    [](DeformJobOptions& o) -> int& { return o.grid.cells; }, kPositive),
        number<float>("--cell-size", "cellSize", Expert, "Explicit cell edge in world units (overrides --cells)",
                      [](DeformJobOptions& o) -> float& { return o.grid.cellSize; }, kPositive, false),
        Setting{"--samples-per-cell", "auto|N", Expert,
                msg("Samples per cell along each axis (n; n^3 per cell), or auto: the densest n from ", kAutoSamplesMin, " to ",
                    kAutoSamplesMax, " whose grid holds at most ", kAutoSampleBudget,
                    " samples (and fits --max-memory), counted on the cells at n = ", kAutoSamplesMin,
                    ": small models get a finer lattice and filter"),
                [](DeformJobOptions& o, const std::string& w) {
                    o.grid.samplesPerAxis = w == "auto" ? kAutoSamplesPerAxis
                                                        : int(parseNumber("--samples-per-cell", w, {2, 16}, true, "auto"));
                },
                [](const DeformJobOptions& o, json& out) {
                    out["samplesPerCell"] =
                        o.grid.samplesPerAxis == kAutoSamplesPerAxis ? json("auto") : json(o.grid.samplesPerAxis);
                },
                [](const DeformJobOptions& o) {
                    return o.grid.samplesPerAxis == kAutoSamplesPerAxis ? std::string("auto")
                                                                        : std::to_string(o.grid.samplesPerAxis);
                }},
        number<float>("--cutoff", "cutoff", Expert, "A Gaussian contributes where alpha*G >= cutoff (1e-3 for thin structures)",
                      [](DeformJobOptions& o) -> float& { return o.grid.cutoff; },
                      {1e-8, 0.999}),
        Setting{"--max-memory", "SIZE", Expert,
                "Refuse a job whose sample grid, or the (block, Gaussian) pair lists of its field evaluation and Stage "
                "II, would need more host memory than this, checked before allocating them: 8G, 512M, ... (default: 3/4 "
                "of physical memory, " + formatBytes(double(defaultMemoryBudget())) + " here)",
                [](DeformJobOptions& o, const std::string& t) { o.grid.maxMemoryBytes = parseByteSize(t, "--max-memory"); },
                [](const DeformJobOptions&, json&) {}, // refuses or runs; never changes a byte
                [](const DeformJobOptions&) { return std::string(); }},
        // The lattice is fine below grid.fineBelow (0: off); --fine-below holds the threshold --fine-cells
        // auto puts there, so the two may come in either order.
        word("--fine-cells", {"auto", "off"}, Expert,
             "Finer Stage II samples where the Gaussians are small: auto gives a cell (2n)^3 samples when the "
             "median largest scale of the Gaussians centred in it is below --fine-below x the sample spacing h/n "
             "(its Gaussians' rest and Stage II filter then use the spacing h/2n); off: n^3 in every cell",
             [](DeformJobOptions& o, const std::string& w) { o.grid.fineBelow = w == "auto" ? o.fineCellsBelow : 0.0f; },
             [](const DeformJobOptions& o) { return o.grid.fineBelow > 0 ? "auto" : "off"; },
             [](const DeformJobOptions& o, json& out) { out["fineBelow"] = o.grid.fineBelow; }),
        Setting{"--fine-below", "FLOAT", Expert,
                "With --fine-cells auto: the median largest Gaussian scale, in units of the spacing h/n, below which "
                "a cell is fine",
                [](DeformJobOptions& o, const std::string& t) {
                    o.fineCellsBelow = float(parseNumber("--fine-below", t, {1e-3, 100.0}, false));
                    if (o.grid.fineBelow > 0) o.grid.fineBelow = o.fineCellsBelow;
                },
                [](const DeformJobOptions&, json&) {}, // --fine-cells writes the threshold in use
                [](const DeformJobOptions& o) { return numberText(o.fineCellsBelow, true); }},
        toggle("--fine-neighbours", "fineNeighbours", Expert, "With --fine-cells auto: also refine the 26 neighbours of each fine cell",
               [](DeformJobOptions& o) -> bool& { return o.grid.fineNeighbours; }),
    };
}

/// Stage II's own split (--split) between two rounds.
std::vector<Setting> splitSettings()
{
    return {
        onOff("--split", "split",
              "auto: split each moving Gaussian whose rest cell's deformation gradient F has its largest singular "
              "value above --split-stretch into two along its longest axis (same mass, mean, covariance and colour), "
              "between two Stage II rounds; off: one round",
              [](DeformJobOptions& o) -> bool& { return o.densify.split; }),
        number<float>("--split-stretch", "splitStretch", Expert,
                      "With --split auto: the largest singular value of a cell's F above which its Gaussians split",
                      [](DeformJobOptions& o) -> float& { return o.densify.splitStretch; }, {1.0, 100.0}),
        number<float>("--split-after", "splitAfter", Expert,
                      "With --split auto: share of the Stage II iterations run before the split (0: split first)",
                      [](DeformJobOptions& o) -> float& { return o.densify.splitAfter; }, {0.0, 1.0}),
        number<float>("--split-offset", "splitOffset", Expert,
                      "With --split auto: the children sit at the mean +- this x sigma along the longest axis (their "
                      "sigma there is sqrt(1 - offset^2) x the parent's)",
                      [](DeformJobOptions& o) -> float& { return o.densify.splitOffset; }, {0.05, double(kMaxSplitOffset)}),
    };
}

/// --curve-split-prune: written only when on, so the hash of earlier runs holds.
Setting curveSplitPruneSetting()
{
    Setting s = number<double>(
        "--curve-split-prune", "curveSplitPrune", Expert,
        "With --curve-split auto and a budget that binds: once it is spent, a split is still made by removing "
        "the faintest Gaussians not split (least visible alpha times mean projected area first) while each "
        "one's cost times this is below the split's expected gain per Gaussian added; 0: never (better in "
        "images on meshes, worse on the field judge of captures; docs/lab/gaussian-budget.md)",
        [](DeformJobOptions& o) -> double& { return o.curve.pruneWorth; }, {0.0, 1e6});
    const auto write = s.write;
    s.write = [write](const DeformJobOptions& o, json& out) {
        if (o.curve.pruneWorth > 0) write(o, out);
    };
    return s;
}

/// --budget-merge: written only with a budget (it does nothing without one).
Setting budgetMergeSetting()
{
    return word("--budget-merge", {"auto", "off"}, Expert,
             "With --max-gaussians and the keep (and no Stage II split or prune): after the keep, each Gaussian the "
             "splits made children of is merged back (same mass, mean, covariance, mass-weighted colour) whole, or "
             "first into runs of three when split twice, least validation loss per Gaussian removed first, until the "
             "model fits the budget; off: the splits spend the budget itself, most expected gain first",
             [](DeformJobOptions& o, const std::string& w) { o.budgetMerge = w == "auto"; },
             [](const DeformJobOptions& o) { return o.budgetMerge ? "auto" : "off"; },
             [](const DeformJobOptions& o, json& out) {
                 if (o.maxGaussians) out["budgetMerge"] = o.budgetMerge;
             });
}

/// --validation-draws: the keep's points.
Setting validationDrawsSetting()
{
    return Setting{"--validation-draws", "auto|N", Expert,
                   msg("With --keep validated or regions: draws of the judge's rule (other seeds) behind the validation "
                       "points that the keep, the budget merge, the splits and the stop choose on; each draw keeps up to ",
                       kValidationInside / kValidationDraws, " x --eval-points inside the model and ",
                       kValidationOutside / kValidationDraws, " x outside; more choose better and take longer. auto: ",
                       kValidationWork, " / the model's Gaussians, from ", kValidationDraws, " to ", 2 * kValidationDraws),
                   [](DeformJobOptions& o, const std::string& w) {
                       o.validationDraws = w == "auto" ? 0 : int(parseNumber("--validation-draws", w, {1, 1000}, true, "auto"));
                   },
                   [](const DeformJobOptions& o, json& out) {
                       out["validationDraws"] = o.validationDraws > 0 ? json(o.validationDraws) : json("auto");
                   },
                   [](const DeformJobOptions& o) {
                       return o.validationDraws > 0 ? std::to_string(o.validationDraws) : std::string("auto");
                   }};
}

/// The steps before Stage II that add Gaussians, and the budget.
std::vector<Setting> candidateSettings()
{
    return {
        onOff("--curve-split", "curveSplit",
              "auto: before Stage II, split each Gaussian that the deformation bends more than one affine map can "
              "follow into three along the bent axis, in the rest pose, and move the children with Stage I again "
              "(most gain first, see --curve-split-max); off: Stage II starts from the Stage I model",
              [](DeformJobOptions& o) -> bool& { return o.curveSplit; }),
        onOff("--validated-split", "validatedSplit",
              "auto: after the curve split, split each moving Gaussian still as Stage I left it in three along "
              "the one of its axes that helps most, where the exact drop of the validation score (the judge's rule, "
              "other seeds) says it pays, largest drops first (needs --keep validated or regions; shares "
              "--curve-split-max); off: no such split",
              [](DeformJobOptions& o) -> bool& { return o.validatedSplit; }, false),
        Setting{"--max-gaussians", "N|Xx|none", User,
                "The most Gaussians the output may hold: N, or a factor of the input's count such as 1.5x (1x: "
                "no growth; none: no budget, the splits add up to 1.25x the model). With the keep (--keep validated "
                "or regions) the splits add their share, Stage II fits the children, and the splits that buy least "
                "are merged back until the model fits (--budget-merge; at 1x nothing is split); else the curve split, "
                "the validated split and Stage II's split spend the budget itself, in that order",
                [](DeformJobOptions& o, const std::string& t) {
                    if (t == "none") {
                        o.maxGaussians.reset();
                        return;
                    }
                    GaussianBudget budget;
                    const std::string error = parseGaussianBudget(t, budget);
                    if (!error.empty()) throw UsageError("--max-gaussians " + error + " or none");
                    o.maxGaussians = budget;
                },
                [](const DeformJobOptions& o, json& out) { out["maxGaussians"] = o.maxGaussians ? o.maxGaussians->text() : "none"; },
                [](const DeformJobOptions& o) { return o.maxGaussians ? o.maxGaussians->text() : std::string("none"); }},
        budgetMergeSetting(),
        number<float>("--curve-split-max", "curveSplitMax", Expert,
                      "At most this many Gaussians added by the curve split and the validated split together, as a share "
                      "of the model's (with a budget the merge does not meet, --budget-merge, the budget instead)",
                      [](DeformJobOptions& o) -> float& { return o.curve.maxAdded; }, {0.0, 16.0}),
        number<int>("--curve-split-rounds", "curveSplitRounds", Expert,
                    "With --curve-split auto: children still bent are split again, up to this many rounds in all",
                    [](DeformJobOptions& o) -> int& { return o.curve.rounds; }, {1, 8}),
        number<double>("--curve-split-fan", "curveSplitFan", Expert,
                       "With --curve-split auto: a Gaussian bent by more than this many of its sigmas is fanned into many "
                       "thin children at once (three rounds of halving could not straighten it); with --keep validated the "
                       "split is made with fans and without and the validation points keep the better; 0: never fan",
                       [](DeformJobOptions& o) -> double& { return o.curve.fanAbove; }, {0.0, 1000.0}),
        curveSplitPruneSetting(),
    };
}

/// The keep's candidates and choices around Stage II, and the prune.
std::vector<Setting> keepSettings()
{
    return {
        Setting{"--curve-shift", "auto|SHARE", Expert,
                "With --keep validated: one more candidate of the keep, the start with each moving Gaussian's mean "
                "moved by this share of the deformation's second-order offset along its axes (where its mass goes "
                "on a curve); auto: the share of 0.25, 0.5, 0.75, 1 the validation points judge best; 0: none",
                [](DeformJobOptions& o, const std::string& w) {
                    if (w == "auto")
                        o.curveShift.reset();
                    else
                        o.curveShift = parseNumber("--curve-shift", w, {0.0, 2.0}, false, "auto");
                },
                [](const DeformJobOptions& o, json& out) { out["curveShift"] = o.curveShift ? json(*o.curveShift) : json("auto"); },
                [](const DeformJobOptions& o) { return o.curveShift ? numberText(*o.curveShift) : std::string("auto"); }},
        word("--keep", {"validated", "regions", "fit"}, Expert,
             "validated: after Stage II keep its start, the curve-shifted start (--curve-shift), its fit or a "
             "mix of them (per region of a 16-cell lattice), whichever is judged best on validation points (the "
             "judge's rule, other seeds), then let each moving Gaussian, heaviest first, take the candidate's "
             "version of it that lowers the validation score; regions: the region mix only; fit: always keep the fit",
             [](DeformJobOptions& o, const std::string& w) {
                 o.keepValidated = w != "fit";
                 o.keepPerGaussian = w == "validated";
             },
             [](const DeformJobOptions& o) { return !o.keepValidated ? "fit" : o.keepPerGaussian ? "validated" : "regions"; },
             [](const DeformJobOptions& o, json& out) {
                 out["keepValidated"] = o.keepValidated;
                 if (!o.keepPerGaussian) out["keepPerGaussian"] = false; // off its default only (older hashes hold)
             }),
        number<int>("--validation-stop", "validationStop", Expert,
                    "With --keep validated or regions: score Stage II's start, then its fit after two steps and every K "
                    "iterations, on the validation points and stop once the score rose by more than 1% of the last "
                    "check's (after two steps and at the K-th iteration: by more than 15% of the start's), or once a "
                    "fit still worse than its start would not be back at the start's score by the last iteration at "
                    "its pace since the last check (0: run every iteration)",
                    [](DeformJobOptions& o) -> int& { return o.validationStop; }, {0, 1000000}),
        validationDrawsSetting(),
        number<float>("--prune-below", "pruneBelow", Expert,
                      "Remove the moving Gaussians whose opacity Stage II leaves below this (before the split and at the "
                      "end; 0: keep every Gaussian)",
                      [](DeformJobOptions& o) -> float& { return o.densify.pruneBelow; }, {0.0, 1.0}),
    };
}

std::vector<Setting> stageTwoSettings()
{
    return {
        Setting{"--iterations", "auto|N", User, msg("Stage II Adam iterations, or auto: up to ", StageTwoOptions::kAutoIterations,
                    ", stopping once the energy fell by less than a fraction ", StageTwoOptions::kAutoStallTolerance, " over ",
                    StageTwoOptions().stallWindow, " iterations (--stall-tolerance sets that fraction)"),
                // --stall-tolerance, a later row, may then refine auto's stop
                [](DeformJobOptions& o, const std::string& w) { setIterations(o.stage2, w); },
                [](const DeformJobOptions& o, json& out) {
                    out["iterations"] = o.stage2.iterations;
                    out["scheduleIterations"] = o.stage2.scheduleIterations;
                },
                [](const DeformJobOptions& o) { return std::to_string(o.stage2.iterations); }},
        number<float>("--boundary-weight", "boundaryWeight", Expert,
                      "lambda2: extra weight of |O* - O| where the target is empty (keeps Gaussians out of empty space)",
                      [](DeformJobOptions& o) -> float& { return o.stage2.boundaryWeight; }, kNonNegative),
        number<float>("--stall-tolerance", "stallTolerance", Expert,
                      "Stop Stage II early when its energy fell by less than this fraction over the last 10 iterations "
                      "(0: run every iteration; a step that raises the energy is always undone, and 6 such in a row end the run)",
                      [](DeformJobOptions& o) -> float& { return o.stage2.stallTolerance; }, {0.0, 1.0}),
        number<float>("--max-mean-step", "maxMeanStep", Expert,
                      "Longest Stage II step of a Gaussian's centre, in its own standard deviations (0: unbounded)",
                      [](DeformJobOptions& o) -> float& { return o.stage2.maxMeanStep; }, kNonNegative),
        toggle("--no-lpf", "lowPassFilter", Expert, "Turn off the adaptive anisotropic low-pass filter",
               [](DeformJobOptions& o) -> bool& { return o.stage2.lowPassFilter; }, false),
        number<int>("--coverage-steps", "coverageSteps", Expert,
                    "Stage II coverage (which Gaussians may touch which samples) holds what a Gaussian can reach in "
                    "this many steps; rebuilt when one leaves it. Speed only: results are the same",
                    [](DeformJobOptions& o) -> int& { return o.stage2.coverageSteps; }, {1, 1000}),
        number<int>("--rebuild-every", "rebuildEvery", Expert,
                    "Also rebuild the Stage II coverage every K iterations (0: only when a Gaussian leaves it). Speed "
                    "only: results are the same",
                    [](DeformJobOptions& o) -> int& { return o.stage2.rebuildEvery; }, {0, 1000000}),
    };
}

std::vector<Setting> outputSettings()
{
    return {
        number<int>("--eval-every", "evalEvery", Expert, "Record the held-out field error every K Stage II iterations in the report",
                    [](DeformJobOptions& o) -> int& { return o.evalEvery; }, kNonNegative, false),
        number<std::size_t>("--eval-points", "evalPoints", Expert,
                            "Held-out points for the field errors; the keep's validation points are drawn in proportion "
                            "(see --validation-draws): about 1 KB a point at SH degree 0 and 4.5 KB at 3 with 20 draws",
                            [](DeformJobOptions& o) -> std::size_t& { return o.heldOut.points; }, {1, 1e12}),
        toggle("--no-eval", "evaluate", Expert, "Skip the held-out field errors",
               [](DeformJobOptions& o) -> bool& { return o.evaluate; }, false),
        recordedWord("--device", "device", {"auto", "cpu", "cuda"},
             deviceHelp("the computing stages run (Stage I update, field targets, sample and held-out warping, held-out "
                        "evaluation, Stage II, --render)"),
             [](DeformJobOptions& o, const std::string& w) { o.device = parseDevice(w); },
             [](const DeformJobOptions& o) { return deviceName(o.device); }),
        toggle("--vdb", "vdb", User,
               "Also write the Stage II model's sampled field (as `to-vdb`): deform's field.vdb; animate's "
               "vdb/field.0000.vdb ... (the sequence naming Houdini and Blender read)",
               [](DeformJobOptions& o) -> bool& { return o.writeVdb; }),
        toggle("--render", "render", User,
               "Also write images: deform's compare.png (rest | Stage I | Stage II from a few orbit views) and "
               "stretched.png (the same three, close up on the most stretched cell holding matter, the rest moved "
               "rigidly there; report.json \"stretched\" says where); animate's preview/frame.0000.png ... and "
               "preview/strip.png (the frames side by side; past 102 frames, 102 spread over the run)",
               [](DeformJobOptions& o) -> bool& { return o.render; }),
    };
}

} // namespace

std::string deviceHelp(const std::string& what)
{
    return "Where " + what + ": auto (CUDA when compiled in and a GPU is present, else CPU; out of GPU memory falls back "
                             "to the CPU), cpu or cuda";
}

const std::vector<Setting>& deformSettings()
{
    static const std::vector<Setting> table = [] {
        std::vector<Setting> all;
        for (auto part : {stageOneSettings, gridSettings, splitSettings, candidateSettings, keepSettings, stageTwoSettings,
                          outputSettings})
            for (Setting& s : part()) all.push_back(std::move(s));
        return all;
    }();
    return table;
}

const Setting& deformSetting(const std::string& flag)
{
    for (const Setting& s : deformSettings())
        if (s.flag == flag) return s;
    throw std::logic_error("no deform setting " + flag);
}

DeformJobOptions deformDefaults()
{
    DeformJobOptions o;
    o.grid.samplesPerAxis = kAutoSamplesPerAxis;
    o.grid.maxMemoryBytes = defaultMemoryBudget();
    return o;
}

json settingsJson(const DeformJobOptions& o)
{
    json settings = json::object();
    for (const Setting& s : deformSettings()) s.write(o, settings);
    return settings;
}

} // namespace splatwarp
