#include "job/DeformPipeline.h"
#include "job/DeformSession.h"
#include "job/DeformSettings.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <numeric>
#include <sstream>

#include <tbb/parallel_invoke.h>

#include "deform/SampleWarp.h"
#include "job/BudgetMerge.h"
#include "job/Judge.h"
#include "job/Selector.h"
#include "job/StageTwoRounds.h"
#include "job/ValidatedSplit.h"
#include "job/StretchedView.h"
#include "vdb/VdbExport.h"
#include "core/AtomicFile.h"
#include "core/Error.h"
#include "core/Memory.h"
#include "core/Progress.h"
#include "core/RunControl.h"
#include "deform/DeformReport.h"
#include "deform/WarpDevice.h"
#include "image/ImageIO.h"
#include "render/Camera.h"
#include "render/ComparisonSheet.h"
#include "stage2/StageTwoDevice.h"

namespace splatwarp {

namespace {

/// Cameras that frame both the rest and the deformed shape.
std::vector<Camera> comparisonCameras(const GaussianCloud& rest, const GaussianCloud& deformed, const DeformJobOptions& o)
{
    GaussianCloud both = rest;
    for (std::size_t i = 0; i < deformed.size(); ++i) both.append(deformed, i);
    OrbitOptions orbit;
    orbit.views = o.renderViews;
    orbit.width = orbit.height = o.renderSize;
    return orbitCameras(both, orbit);
}

/// The most stretched region of the deformation, from its warped samples (render only).
std::optional<StretchedRegion> stretchedRegionOf(const SampleSet& warped, const DeformJobOptions& o)
{
    return o.render ? mostStretchedRegion(warped) : std::nullopt;
}

/// stretched.png: a close-up of the most stretched region (StretchedView.h, found by the refine
/// from its warped samples); the report's "stretched" says where it is.
void writeStretchedView(const DeformRest& rest, const std::optional<StretchedRegion>& region, const GaussianCloud& stage1,
                        const GaussianCloud& fitted, const DeformJobOptions& o, const std::string& path,
                        FrameReport& report)
{
    if (!region) {
        progress("stretched.png: no cell with matter to show; not written");
        return;
    }
    RenderOptions render;
    render.device = rest.device;
    writePng(path, renderStretchedCloseUp(rest.model, stage1, fitted, *region, o.renderSize, render));
    report.stretched = StretchedRecord{region->cell, region->stretch, region->radius, region->warpedCentre};
    report.outputs["stretched"] = path;
}

/// The optional outputs of Stage II's result: field.vdb, compare.png and stretched.png.
void writeExtras(const DeformRest& rest, const std::optional<StretchedRegion>& stretched, const GaussianCloud& stage1,
                 const GaussianCloud& fitted, const DeformJobOptions& o, const FrameOutputs& out, FrameReport& report)
{
    Stopwatch clock;
    if (!out.vdb.empty()) {
        SampleGridOptions gridOptions = o.grid;
        gridOptions.device = rest.device;
        gridOptions.fineBelow = 0.0f; // field.vdb is one uniform lattice, as `to-vdb` writes
        const SampleGrid fieldGrid = runStage("field.vdb sample grid", [&] { return SampleGrid(fitted, gridOptions); });
        VdbExportOptions vo;
        vo.source = out.deformed;
        vo.threaded = o.grid.threaded;
        writeSampleGridVdb(out.vdb, fieldGrid, vo);
        report.outputs["field"] = out.vdb;
        report.timingsMs["vdb"] = clock.ms();
    }
    if (!out.compare.empty()) {
        clock.reset();
        ComparisonSheetOptions sheetOptions;
        sheetOptions.render.device = rest.device;
        const Image sheet = renderComparisonSheet({&rest.model, &stage1, &fitted}, {"rest", "stage I", "stage II"},
                                                  comparisonCameras(rest.model, fitted, o), sheetOptions);
        writePng(out.compare, sheet);
        report.outputs["compare"] = out.compare;
        if (!out.stretched.empty()) writeStretchedView(rest, stretched, stage1, fitted, o, out.stretched, report);
        report.timingsMs["render"] = clock.ms();
    }
}

/// The errors of one frame: the judge (what `eval` prints for the same files) and the error at
/// the training lattice (its cells, cutoff and rest filter; what Stage II fits).
struct FrameErrors {
    std::optional<Judge> judge;
    std::optional<HeldOutPoints> lattice;
    std::optional<FieldErrorTarget> latticeTarget;

    FrameErrors() = default;
    FrameErrors(const DeformRest& rest, const Deformation& deformation, const DeformJobOptions& o)
    {
        prepare(rest, deformation, o);
    }
    /// The judge's points warped and the training lattice's target (nothing without a judge).
    void prepare(const DeformRest& rest, const Deformation& deformation, const DeformJobOptions& o)
    {
        if (!rest.judge) return;
        judge.emplace(rest.model, *rest.judge, deformation, o.grid.threaded);
        lattice = *rest.latticePoints;
        warpHeldOutPoints(*lattice, deformation, o.grid.threaded);
        latticeTarget = rotatedTarget(*rest.latticeRest, *lattice);
    }

    /// The judge's errors and the training lattice's of a model, with progress lines; none
    /// when the run does not evaluate.
    std::optional<ModelErrors> record(const GaussianCloud& model, const std::string& label) const
    {
        if (!judge) return std::nullopt;
        ModelErrors e{judge->judge(model), evaluateHeldOut(*latticeTarget, model, *lattice), lattice->features.filterVariance};
        progress(label + ", judged as `splatwarp eval` prints it:");
        std::istringstream lines(judgeText(e.judge));
        for (std::string line; std::getline(lines, line);) progress(line);
        progress(msg(label, " error at the training lattice: opacity ", e.lattice.opacity, ", color ", e.lattice.color));
        return e;
    }
};

/// A rigid spec (every graph node held, one rigid motion): Stage I moves every Gaussian by that
/// motion, and the filter of a rotated cell is the rotated filter, so the warped field is exactly
/// the Stage I model's and Stage II has nothing to fit (run anyway, it only adds noise: at best
/// its first steps are all rejected). Returns the Stage I model with both stages judged.
GaussianCloud skipStageTwo(DeformRest& rest, const Deformation& deformation, const StageOneResult& stage1,
                           const DeformJobOptions& o, FrameReport& report, std::optional<StretchedRegion>& stretched)
{
    progress("Stage II: skipped (a rigid spec: the Stage I model is the fitted one)");
    StageTwoRecord& s2 = report.stage2.emplace();
    s2.skipped = true;
    s2.gaussians = stage1.deformed.size();
    report.timingsMs["stage2"] = 0.0;
    Stopwatch clock;
    const FrameErrors errors(rest, deformation, o);
    if (errors.judge) { // one model, judged once for both stages
        report.stage1Errors = s2.errors = errors.record(stage1.deformed, "Stage I");
        report.timingsMs["evaluate"] = rest.heldOutMs + rest.latticeMs + clock.ms();
    }
    if (o.render) { // stretched.png: the samples are warped for it alone
        SampleSet samples = rest.grid->samples();
        warpSamplesOn(samples, deformation, {rest.device, o.grid.threaded});
        stretched = mostStretchedRegion(samples);
    }
    return stage1.deformed;
}

/// Stage II's cold start: Stage I's model with its moving flags and rest cells, and with the bent
/// Gaussians split and moved again (--curve-split; the report's "curveSplit", judged when evaluating).
struct ColdStart {
    GaussianCloud model;
    GaussianCloud shifted; ///< the curve shift of model (empty when off): a candidate of the keep
    std::vector<std::uint8_t> moving;
    std::vector<std::int32_t> cells;
    std::vector<float> curve; ///< [N,3] phi's second-order offsets of model's Gaussians, while the splits and shift need them
    std::vector<std::int32_t> parent; ///< [N] the rest Gaussian each of model's comes from (the budget's merge)
    std::size_t added = 0, removed = 0; ///< by the splits before Stage II (removed: to make room for children)
    /// Gaussians added, net: what the splits before Stage II spent of the budget.
    std::size_t grown() const { return added - removed; }
    bool changed() const { return added > 0 || removed > 0; }
    /// The arrays as the steps that change them take them (stage2/Densify.h).
    FitState state() { return {model, moving, cells, &curve, &parent}; }
};

} // namespace

bool mergesToBudget(const DeformJobOptions& o)
{
    return o.maxGaussians && o.budgetMerge && o.keepValidated && !o.densify.split && !(o.densify.pruneBelow > 0);
}

namespace {

/// Whether the merge meets the budget on a model of `n`: not at no growth (1x), where merging every
/// split back judges worse than not splitting (lastchance.splat bend 0.0586 against 0.0479).
bool mergesAt(const DeformJobOptions& o, std::size_t n)
{
    return mergesToBudget(o) && o.maxGaussians->added(n) > 0;
}

/// The Gaussians the splits before and inside Stage II may add to a model of `n`: the curve split's
/// share (which the validated split shares; Stage II's split is then unbounded) when there is no
/// budget or the merge meets it after the keep, else the budget itself.
std::size_t splitBudget(const DeformJobOptions& o, std::size_t n)
{
    if (!o.maxGaussians || mergesAt(o, n)) return std::size_t(double(o.curve.maxAdded) * double(n));
    return o.maxGaussians->added(n);
}

/// The curve split; with validation points, split with fans and without and keep the one they
/// judge better (fans win where a few Gaussians are bent far beyond three halvings, playbot-31k;
/// they lose where many thin ones are, guitar: docs/lab/fidelity-study.md). Where no Gaussian was
/// bent far enough to fan, both are the same split: it is made and scored once.
CurveSplitResult curveSplitOf(const DeformRest& rest, const Deformation& deformation, const StageOneResult& stage1,
                              const DeformJobOptions& o, const Selector* validation, CurveSplitRecord& record)
{
    CurveSplitOptions co = o.curve;
    co.threaded = o.grid.threaded;
    co.maxAddedCount = splitBudget(o, rest.model.size());
    auto split = [&](double fanAbove) {
        co.fanAbove = fanAbove;
        return curveSplit(rest.model, rest.rig, rest.graph, deformation.transforms, deformation.nodeMoving, stage1,
                          o.stage1, co);
    };
    CurveSplitResult cs = split(o.curve.fanAbove);
    if (!validation || !(o.curve.fanAbove > 0)) return cs;
    if (cs.beyondFan == 0) { // nothing fanned: this is also the split without fans
        record.validationWithFans = record.validationWithoutFans = validation->score(cs.deformed);
        return cs;
    }
    CurveSplitResult three = split(0.0);
    const Selection s = validation->best({&cs.deformed, &three.deformed});
    record.validationWithFans = s.scores[0];
    record.validationWithoutFans = s.scores[1];
    const double ms = cs.ms + three.ms; // both splits ran
    if (s.best == 1) {
        cs = std::move(three);
        record.fans = false;
    }
    cs.ms = ms;
    return cs;
}

/// The cold start's curve shift, a candidate of the validated keep (empty without validation
/// points or with --curve-shift 0; the report's "curveShift", judged when evaluating).
GaussianCloud curveShiftOf(const GaussianCloud& start, const std::vector<float>& curve, const DeformJobOptions& o,
                           const FrameErrors& errors, const Selector* validation, FrameReport& report)
{
    if (!validation || o.curveShift == 0.0) return {};
    const std::vector<double> shares =
        o.curveShift ? std::vector<double>{*o.curveShift} : std::vector<double>(std::begin(kCurveShares), std::end(kCurveShares));
    CurveShiftChoice c = validation->bestCurveShift(start, curve, shares);
    CurveShiftRecord& r = report.curveShift.emplace();
    r = {c.share, !o.curveShift, shares, c.scores, c.ms, std::nullopt};
    report.timingsMs["curveShift"] = c.ms;
    progress(msg("curve shift: share ", c.share, " of the second-order offset (", int(c.ms), " ms)"));
    r.errors = errors.record(c.model, "Curve shift");
    return std::move(c.model);
}

/// --validated-split: the splits the validation points measure to pay, within what is left of the
/// curve split's budget (the report's "validatedSplit").
void splitByValidation(const DeformRest& rest, const Deformation& deformation, const StageOneResult& stage1,
                       const DeformJobOptions& o, const Selector& validation, ColdStart& c, FrameReport& report)
{
    const std::size_t allowed = splitBudget(o, rest.model.size());
    const std::size_t budget = allowed > c.grown() ? allowed - c.grown() : 0;
    StageOneOptions s1 = o.stage1;
    s1.threaded = o.grid.threaded;
    const ValidatedSplitReport r =
        validatedSplit(validation.points(), rest.model, deformation, s1, stage1.deformed, budget, c.state());
    c.added += r.added;
    report.validatedSplit = ValidatedSplitRecord{r, budget};
    report.timingsMs["validatedSplit"] = r.ms;
}

/// --curve-split on the cold start (the report's "curveSplit"); returns phi's second-order offsets
/// of the start's Gaussians.
std::vector<float> splitBent(const DeformRest& rest, const Deformation& deformation, const StageOneResult& stage1,
                             const DeformJobOptions& o, const FrameErrors& errors, const Selector* validation,
                             ColdStart& c, FrameReport& report)
{
    CurveSplitRecord& record = report.curveSplit.emplace();
    CurveSplitResult cs = curveSplitOf(rest, deformation, stage1, o, validation, record);
    record.options = o.curve;
    record.roundsUsed = cs.rounds;
    record.split = cs.split;
    record.added = cs.added;
    record.pruned = cs.pruned;
    record.gaussians = cs.deformed.size();
    record.ms = cs.ms;
    report.timingsMs["curveSplit"] = cs.ms;
    const std::string removed = cs.pruned ? msg(", ", cs.pruned, " faint ones removed to make room") : std::string();
    progress(msg("curve split: ", cs.split, " bent Gaussians split, ", cs.added, " added", removed, ": ", cs.deformed.size(),
                 " Gaussians (", int(cs.ms), " ms)"));
    if (cs.added > 0) {
        c.model = std::move(cs.deformed);
        c.moving = std::move(cs.moving);
        c.added = cs.added;
        c.removed = cs.pruned;
        std::vector<std::int32_t> cells(cs.parent.size()); // children filter as their parent's rest cell
        for (std::size_t i = 0; i < cs.parent.size(); ++i) cells[i] = c.cells[std::size_t(cs.parent[i])];
        c.cells = std::move(cells);
        c.parent = std::move(cs.parent);
        record.errors = errors.record(c.model, "Curve split");
    }
    return std::move(cs.curve);
}

/// --keep validated: Stage II's start, its curve shift (when made), the fit or a region mix of them,
/// whichever the validation points judge best (job/StageTwoChoice.h; the report's stage2 "keep").
GaussianCloud keepValidated(const Selector& validation, const GaussianCloud& startModel, const GaussianCloud* shifted,
                            GaussianCloud fitted, bool sameGaussians, bool perGaussian, KeepRecord& record)
{
    std::vector<StageTwoCandidate> candidates{{"start", &startModel}};
    if (shifted && !shifted->empty()) candidates.push_back({"shifted", shifted});
    candidates.push_back({"fit", &fitted});
    for (const StageTwoCandidate& c : candidates) record.candidates.push_back(c.name);
    GaussianCloud kept = validation.regionMix(candidates, sameGaussians, record.choice);
    if (!perGaussian || !sameGaussians || kept.size() != startModel.size()) return kept;
    return validation.perGaussian(candidates, std::move(kept), record.perGaussian.emplace());
}

/// The Gaussians the kept model gained and lost: the curve split's and, unless --keep validated went
/// back to a start (`keptName`: the keep's choice, "" without a keep), those of the split and prune
/// inside Stage II.
void recordGaussianCounts(const ColdStart& cold, const DensifyCounts& counts, const DeformJobOptions& o,
                          const GaussianCloud& kept, const std::string& keptName, StageTwoRecord& stage2)
{
    const bool fitKept = keptName.empty() || keptName == "fit" || keptName == "mix";
    stage2.densify = o.densify;
    stage2.densifyMs = counts.ms;
    stage2.gaussiansAdded = cold.added + (fitKept ? counts.split : 0);
    stage2.gaussiansRemoved = cold.removed + (fitKept ? counts.pruned : 0) + (stage2.budgetMerge ? stage2.budgetMerge->removed : 0);
    stage2.gaussians = kept.size();
    if (o.densify.split || o.densify.pruneBelow > 0)
        progress(msg("Stage II: ", counts.split, " Gaussians added by splits, ", counts.pruned, " pruned", fitKept ? "" : " (not kept)",
                     ": ", kept.size(), " Gaussians"));
}

/// Warp a copy of the rest samples (the rest samples stay untouched for the next frame).
SampleSet warpedSamples(const DeformRest& rest, const Deformation& deformation, const DeformJobOptions& o,
                        FrameReport& report)
{
    Stopwatch clock;
    SampleSet samples = rest.grid->samples();
    const char* warpDevice = deviceName(warpSamplesOn(samples, deformation, {rest.device, o.grid.threaded}));
    report.timingsMs["warpSamples"] = clock.ms();
    report.warpDevice = warpDevice;
    progress(msg("warped ", rest.grid->stats().samples, " samples in ", int(clock.ms()), " ms on ", warpDevice));
    return samples;
}

/// The judge's error every --eval-every Stage II iterations (report "evalCurve").
struct EvalCurve {
    const FrameErrors& errors;
    std::vector<CurvePoint> points;

    std::function<void(int, const GaussianCloud&)> onEval(bool on)
    {
        if (!on) return {};
        return [this](int iteration, const GaussianCloud& current) {
            points.push_back({iteration, errors.judge->fieldError(current)});
            progress(msg("Stage II iteration ", iteration, ": judged opacity error ", points.back().error.opacity));
        };
    }
    /// Drops the points after an iteration: a run that fell back to the CPU repeats them.
    std::function<void(int)> dropAfter()
    {
        return [this](int after) {
            points.erase(std::remove_if(points.begin(), points.end(), [&](const CurvePoint& p) { return p.iteration > after; }),
                         points.end());
        };
    }
};

/// One frame's refine as its steps see it: what they read, and the state they change in the order
/// the steps of refineSteps() fill it.
struct Refine {
    DeformRest& rest;
    const Deformation& deformation;
    const StageOneResult& stage1;
    const DeformJobOptions& o;
    const StageTwoStart& start;
    FrameReport& report;
    FrameErrors errors;                 ///< judgeStageOne: the judge's and the training lattice's (none without --eval)
    std::optional<Selector> validation; ///< validation: for --keep validated or regions
    SampleSet samples;                  ///< warp: the rest samples moved by the deformation
    ColdStart cold;                     ///< Stage I's model, then with the splits and shift before Stage II
    GaussianCloud fitted;               ///< stage2's fit, then the keep's choice
    GaussianCloud startModel;           ///< Stage II's start, a candidate of the keep
    EvalCurve curve{errors};            ///< --eval-every
    DensifyCounts counts;               ///< Stage II's split and prune
    std::optional<double> rejectedStart; ///< the warm start's energy when the frame went back to the cold start
    double rejectedMs = 0;
    bool warm = false;
    std::string keptName; ///< the keep's choice ("" without a keep)

    Refine(DeformRest& r, const Deformation& d, const StageOneResult& s1, const DeformJobOptions& options,
           const StageTwoStart& st, FrameReport& rep)
        : rest(r), deformation(d), stage1(s1), o(options), start(st), report(rep),
          cold{s1.deformed, {}, s1.moving, r.grid->gaussianCell(), {}, {}, 0}
    {
        cold.parent.resize(s1.deformed.size());
        std::iota(cold.parent.begin(), cold.parent.end(), std::int32_t(0));
    }
    const Selector* validating() const { return validation ? &*validation : nullptr; }
    // What runs, from the options alone (the phases are counted before any step runs).
    bool judged() const { return rest.judge.has_value(); }
    bool validates() const { return o.keepValidated; }
    bool shifts() const { return validates() && o.curveShift != 0.0; }
};

/// A step of the refine: it runs when `runs` says so, in the order of refineSteps(); `phase` names
/// it in the progress a driver sees (nullptr: a step within another's phase).
struct RefineStep {
    const char* name; ///< as a recipe names the step where it is one (job/Recipe.h)
    const char* phase;
    bool (*runs)(const Refine&);
    void (*run)(Refine&);
};

void warpStep(Refine& f)
{
    f.samples = warpedSamples(f.rest, f.deformation, f.o, f.report);
}

void judgeStageOneStep(Refine& f)
{
    Stopwatch clock;
    f.errors.prepare(f.rest, f.deformation, f.o);
    f.report.stage1Errors = f.errors.record(f.stage1.deformed, "Stage I");
    f.report.timingsMs["evaluate"] = f.rest.heldOutMs + f.rest.latticeMs + clock.ms();
}

/// The selector's validation points warped (the judge's rule with another seed).
void validationStep(Refine& f)
{
    f.validation.emplace(f.rest.model, *f.rest.validation, f.deformation, f.o.grid.threaded);
}

void curveSplitStep(Refine& f)
{
    f.cold.curve = splitBent(f.rest, f.deformation, f.stage1, f.o, f.errors, f.validating(), f.cold, f.report);
}

/// Without the curve split, the curve shift still needs phi's second-order offsets of the start.
void curveOffsetsStep(Refine& f)
{
    f.cold.curve = stageOneBendingOf(f.rest.model, f.rest.rig, f.rest.graph, f.deformation.transforms,
                                     f.stage1.deformed, f.stage1.moving, f.o.stage1).curve;
}

void validatedSplitStep(Refine& f)
{
    splitByValidation(f.rest, f.deformation, f.stage1, f.o, *f.validation, f.cold, f.report);
}

void curveShiftStep(Refine& f)
{
    f.cold.shifted = curveShiftOf(f.cold.model, f.cold.curve, f.o, f.errors, f.validating(), f.report);
}

/// Stage II from the cold start (or animate's warm start, sent back cold when it rejects the fit).
void stageTwoStep(Refine& f)
{
    f.cold.curve = std::vector<float>(); // not needed past the shift: free it before Stage II
    checkCancelled();
    const DeformJobOptions& o = f.o;
    f.fitted = f.cold.model;
    if (f.start.change) { // a warm start corrects each Stage I Gaussian: a split start stays cold
        GaussianCloud warm = f.stage1.deformed;
        f.start.change(f.stage1, warm);
        if (!f.cold.changed()) f.fitted = std::move(warm);
    }
    f.warm = f.start.change && !f.cold.changed();
    if (o.keepValidated) f.startModel = f.fitted;
    StageTwoOptions s2 = o.stage2;
    s2.device = f.rest.device;
    s2.maxMemoryBytes = o.grid.maxMemoryBytes;
    if (f.validation && o.validationStop > 0) { // the keep's points judge when the fit stops improving
        // The checks between the first (the start, a keep candidate) and the last (the fit) are not
        // scored again: each forgets the one before it, so the remembered evaluations stay the
        // keep's (lastchance bend at twice the validation points, alternated three times: peak
        // 858-864 -> 855-858 MB).
        s2.heldOutStop.score = [&v = *f.validation, checks = 0](const GaussianCloud& m) mutable {
            if (checks++ >= 2) v.forgetLatest();
            return v.score(m);
        };
        s2.heldOutStop.every = o.validationStop;
    }
    DensifyJobOptions densify = o.densify; // Stage II's split spends what the splits before it left
    if (o.maxGaussians) densify.maxSplits = splitBudget(o, f.rest.model.size()) - f.cold.grown();
    auto fit = [&] {
        progress(msg("Stage II: ", o.stage2.iterations, " iterations on ", std::count(f.cold.moving.begin(), f.cold.moving.end(), 1), " moving Gaussians"));
        f.curve.points.clear();
        f.counts = DensifyCounts();
        return fitInRounds(f.fitted, f.samples, f.cold.moving, f.cold.cells, s2, densify, f.curve.onEval(o.evalEvery > 0),
                           o.evalEvery, f.counts, f.curve.dropAfter());
    };
    StageTwoReport r2 = fit();
    if (f.warm && f.start.rejects && f.start.rejects(r2)) {
        f.rejectedMs = r2.msTotal;
        f.rejectedStart = r2.energies.empty() ? 0.0 : r2.energies.front().total;
        progress(msg("Stage II: the warm start (energy ", *f.rejectedStart, ") is rejected; fitting from the cold start"));
        f.fitted = f.cold.model;
        r2 = fit();
    }
    StageTwoRecord& record = f.report.stage2.emplace();
    record.fit = std::move(r2);
    record.grid = f.rest.grid->stats();
    record.gridOptions = f.rest.grid->options();
    record.options = o.stage2;
    checkCancelled();
}

/// Say when Stage II ended while its fit still improved on the validation points (kStillImproving):
/// more iterations may fit closer (the donut: 50 more bought it 6-8%).
void adviseIterations(const StageTwoReport& fit, const KeepRecord& keep, int iterations)
{
    const auto named = std::find(keep.candidates.begin(), keep.candidates.end(), "fit");
    const std::size_t i = std::size_t(named - keep.candidates.begin());
    if (named == keep.candidates.end() || i >= keep.choice.scores.size()) return;
    const double fall = stillImprovingBy(fit, keep.choice.scores[i]);
    if (fall <= 0) return;
    progress(msg("Stage II: the fit was still improving when it ended (validation score ", std::round(1000.0 * fall) / 10.0,
                 "% lower than at iteration ", fit.heldOutChecks.back().first, "); --iterations ", 2 * iterations,
                 " may fit closer, in about twice Stage II's time"));
}

void keepStep(Refine& f)
{
    KeepRecord& keep = f.report.stage2->keep.emplace();
    f.fitted = keepValidated(*f.validation, f.rejectedStart ? f.cold.model : f.startModel, &f.cold.shifted,
                             std::move(f.fitted), f.counts.split == 0 && f.counts.pruned == 0, f.o.keepPerGaussian, keep);
    f.keptName = keep.choice.kept;
    f.report.timingsMs["keep"] = keep.ms();
    adviseIterations(f.report.stage2->fit, keep, f.o.stage2.iterations);
}

/// --max-gaussians met after the keep (job/BudgetMerge.h): the split Gaussians whose fitted children
/// buy least merged back. After the per-Gaussian choice, not before it on the region mix: guitar
/// twist 0.0733 against 0.0752 judged (the no-budget default: 0.0709).
void budgetMergeStep(Refine& f)
{
    BudgetMergeReport& r = f.report.stage2->budgetMerge.emplace();
    f.fitted = mergeToBudget(f.validation->points(), f.fitted, f.cold.parent, f.o.maxGaussians->limit(f.rest.model.size()), r);
    f.report.timingsMs["budgetMerge"] = r.ms;
    const std::string scores = r.merged ? msg(", validation ", r.before, " -> ", r.after) : std::string();
    progress(msg("budget: ", r.merged, " of ", r.families, " split Gaussians merged back whole, ", r.mergedToRuns,
                 " into runs of three, ", r.removed, " removed: ", f.fitted.size(), " Gaussians (at most ", r.limit, ")",
                 scores, " (", int(r.ms), " ms)"));
}

/// What the kept model holds and how it was made (the report's stage2 counts, start and curve).
void recordStep(Refine& f)
{
    StageTwoRecord& record = *f.report.stage2;
    recordGaussianCounts(f.cold, f.counts, f.o, f.fitted, f.keptName, record);
    if (f.o.maxGaussians) record.gaussianBudget = f.o.maxGaussians->limit(f.rest.model.size());
    f.report.timingsMs["stage2"] = record.fit.msTotal + f.rejectedMs + f.counts.ms;
    if (f.start.change) record.start = f.warm && !f.rejectedStart ? "warm" : "cold";
    record.warmEnergy = f.rejectedStart;
    if (f.o.evalEvery > 0) record.evalCurve = std::move(f.curve.points);
}

void judgeStep(Refine& f)
{
    f.report.stage2->errors = f.errors.record(f.fitted, "Stage II");
}

bool always(const Refine&) { return true; }

/// The refine's steps in run order: the recipe's steps (job/Recipe.h: curveSplit, validatedSplit,
/// curveShift, stage2 with its split, keep) with the warp and the judge around them. A new step is
/// a row here, its settings rows in job/DeformSettings.cpp, its record in job/FrameReport.h.
const std::vector<RefineStep>& refineSteps()
{
    static const std::vector<RefineStep> steps = {
        {"warp", "warp", always, warpStep},
        {"judgeStageOne", "judge Stage I", [](const Refine& f) { return f.judged(); }, judgeStageOneStep},
        {"validation", nullptr, [](const Refine& f) { return f.validates(); }, validationStep},
        {"curveSplit", "curve split", [](const Refine& f) { return f.o.curveSplit; }, curveSplitStep},
        {"curveOffsets", nullptr, [](const Refine& f) { return !f.o.curveSplit && f.shifts(); }, curveOffsetsStep},
        {"validatedSplit", "validated split", [](const Refine& f) { return f.validates() && f.o.validatedSplit; },
         validatedSplitStep},
        {"curveShift", "curve shift", [](const Refine& f) { return f.shifts(); }, curveShiftStep},
        {"stage2", nullptr, always, stageTwoStep},
        {"keep", "keep", [](const Refine& f) { return f.validates(); }, keepStep},
        {"budgetMerge", nullptr, [](const Refine& f) { return f.validates() && mergesAt(f.o, f.rest.model.size()); },
         budgetMergeStep},
        {"record", nullptr, always, recordStep},
        {"judge", "judge", [](const Refine& f) { return f.judged(); }, judgeStep},
    };
    return steps;
}

/// Stage II and the steps around it on a posed frame; returns the model kept.
GaussianCloud stageTwo(DeformRest& rest, const Deformation& deformation, const StageOneResult& stage1,
                       const DeformJobOptions& o, const StageTwoStart& start, FrameReport& report,
                       std::optional<StretchedRegion>& stretched)
{
    if (rigidMotionOf(deformation)) return skipStageTwo(rest, deformation, stage1, o, report, stretched);
    Refine f(rest, deformation, stage1, o, start, report);
    int phases = 0;
    for (const RefineStep& step : refineSteps()) phases += step.phase && step.runs(f);
    StepProgress steps(phases);
    for (const RefineStep& step : refineSteps()) {
        if (!step.runs(f)) continue;
        if (step.phase) steps.start(step.phase);
        step.run(f);
    }
    stretched = stretchedRegionOf(f.samples, o);
    return std::move(f.fitted);
}

} // namespace

GraphOptions graphOptionsOf(const DeformSpec& spec, const DeformJobOptions& o)
{
    GraphOptions g = spec.graph;
    if (o.nodes) g.nodes = *o.nodes;
    if (o.k) g.k = *o.k;
    if (o.seed) g.seed = *o.seed;
    return g;
}

namespace {

/// Whether the run judges (the held-out errors: the judge's points and the training lattice's).
bool judges(const DeformJobOptions& o) { return o.evaluate || o.evalEvery > 0; }

/// The held-out point options on the rest side's device.
HeldOutOptions heldOutOn(const DeformRest& rest, const DeformJobOptions& o)
{
    HeldOutOptions h = o.heldOut;
    h.device = rest.device;
    return h;
}

/// The rest field sampled into sparse cells (every frame warps a copy of it) and, when judging,
/// the training lattice's points drawn from it.
void prepareGridOf(DeformRest& rest, const DeformJobOptions& o)
{
    Stopwatch clock;
    SampleGridOptions gridOptions = o.grid;
    gridOptions.device = rest.device;
    gridOptions.extraBytesPerSample += stageTwoBytesPerSample(rest.model.shDegree);
    rest.grid = runStage("sample grid", [&] { return std::make_unique<SampleGrid>(rest.model, gridOptions); });
    rest.sampleGridMs = clock.ms();
    if (!judges(o)) return;
    clock.reset();
    rest.latticePoints = drawHeldOutPoints(*rest.grid, heldOutOn(rest, o));
    rest.latticeRest = unrotatedTarget(rest.model, *rest.latticePoints);
    rest.latticeMs = clock.ms();
}

/// Draws of the judge's rule behind the keep's validation points; 0 without the keep.
int validationDrawsOf(const DeformRest& rest, const DeformJobOptions& o)
{
    if (!o.keepValidated) return 0;
    return o.validationDraws > 0 ? o.validationDraws : autoValidationDraws(rest.model.size());
}

/// Refuse held-out and validation points past --max-memory before any is drawn: --eval-points
/// 4000000 took train-1000's deform to 19.2 GB (8 M validation points at SH 3).
void checkPointMemory(const DeformRest& rest, const DeformJobOptions& o)
{
    const int draws = validationDrawsOf(rest, o);
    if (!judges(o) && draws == 0) return;
    checkEvalPointMemory(o.heldOut.points, rest.model.shStride(), judges(o), draws, o.grid.maxMemoryBytes, "--eval-points");
}

/// The selector's validation points at rest (the keep's).
void prepareValidationOf(DeformRest& rest, const DeformJobOptions& o)
{
    if (!o.keepValidated) return;
    Stopwatch clock;
    HeldOutOptions validation = heldOutOn(rest, o);
    validation.seed ^= kValidationSeedXor;
    const int draws = validationDrawsOf(rest, o);
    rest.validation = prepareValidationRest(rest.model, validation, draws);
    rest.validationMs = clock.ms();
    progress(msg("validation: ", rest.validation->unrotated.size(), " points from ", draws, " draws of the judge's rule (",
                 int(rest.validationMs), " ms)"));
}

/// The judge's held-out points at rest.
void prepareJudgeOf(DeformRest& rest, const DeformJobOptions& o)
{
    if (!judges(o)) return;
    Stopwatch clock;
    rest.judge = prepareJudgeRest(rest.model, heldOutOn(rest, o));
    rest.heldOutMs = clock.ms();
    progress(msg("judge: ", o.heldOut.points, " held-out points in the rest model's active region (", int(rest.heldOutMs),
                 " ms)"));
}

/// The rest side past the model: graph, Stage I rig, sample grid, the validation and judge points.
void prepareRestOf(DeformRest& rest, const DeformJobOptions& o, const GraphOptions& graph)
{
    if (o.maxGaussians) o.maxGaussians->limit(rest.model.size()); // refused before any work
    rest.warnings = outlierWarnings(rest.model);
    for (const CloudWarning& w : rest.warnings) progress(msg(o.input, ": ", w.message));
    Stopwatch clock;
    rest.graph = DeformationGraph::build(rest.model, graph, o.ed.threaded);
    rest.graphMs = clock.ms();
    progress(msg("deformation graph: ", rest.graph.nodeCount(), " nodes, k = ", rest.graph.k(), " (", int(rest.graphMs), " ms)"));
    clock.reset();
    rest.rig = prepareStageOne(rest.model, rest.graph, o.stage1);
    rest.rigMs = clock.ms();
    StageOneOptions stageOneOptions = o.stage1;
    stageOneOptions.device = rest.device;
    rest.stageOne = std::make_unique<StageOneUpdater>(rest.model, rest.rig, rest.graph, stageOneOptions);
    if (o.stage1Only) return;
    checkPointMemory(rest, o);
    // The three need only the rest model. On the CPU they run at once, each filling the cores the
    // others' serial parts leave idle (guitar: 1.3 cores busy on average one after another); each
    // is deterministic for any schedule, so the bytes are the same.
    const auto grid = [&] { prepareGridOf(rest, o); };
    const auto validation = [&] { prepareValidationOf(rest, o); };
    const auto judge = [&] { prepareJudgeOf(rest, o); };
    if (!rest.device.cuda() && o.grid.threaded) {
        tbb::parallel_invoke(grid, validation, judge);
    } else {
        grid();
        validation();
        judge();
    }
}

} // namespace

std::unique_ptr<DeformRest> prepareDeformRest(const DeformJobOptions& o, const GraphOptions& graph)
{
    auto rest = std::make_unique<DeformRest>();
    rest->device = resolveDevice(o.device); // before any work: fails when the device cannot run
    Stopwatch clock;
    ReadOptions readOptions;
    readOptions.dropInvalid = o.dropInvalid;
    rest->model = readGaussians(o.input, readOptions, &rest->read);
    for (const std::string& note : rest->read.notes) progress(o.input + ": " + note);
    if (rest->model.empty())
        throw InputError(msg(o.input, ": no Gaussians", rest->read.dropped ? " left after dropping unusable ones" : ""));
    rest->readMs = clock.ms();
    progress(msg("read ", rest->model.size(), " Gaussians (SH degree ", rest->model.shDegree, ") from ", o.input));
    prepareRestOf(*rest, o, graph);
    return rest;
}

std::unique_ptr<DeformRest> prepareDeformRest(const DeformJobOptions& o, const GraphOptions& graph, GaussianCloud model,
                                              ReadReport read)
{
    auto rest = std::make_unique<DeformRest>();
    rest->device = resolveDevice(o.device);
    if (model.empty()) throw InputError(msg(o.input, ": no Gaussians"));
    model.checkConsistent();
    rest->model = std::move(model);
    rest->read = std::move(read);
    prepareRestOf(*rest, o, graph);
    return rest;
}

FrameResult poseFrame(DeformRest& rest, const DeformSpec& spec, const DeformJobOptions& o)
{
    Stopwatch clock;
    FrameResult f{solveDeformation(rest.graph, rest.model, spec, o.ed), {}, std::nullopt, std::nullopt, {}, 0.0};
    f.deformation.report.graphMs = rest.graphMs;
    f.stage1 = rest.stageOne->apply(f.deformation.transforms, f.deformation.nodeMoving);
    f.stage1.timings.rigMs = rest.rigMs;
    progress(msg("Stage I: ", f.stage1.movingCount, " of ", rest.model.size(), " Gaussians moved (", int(rest.rigMs),
                 " ms weights, ", int(f.stage1.timings.updateMs), " ms update on ", deviceName(f.stage1.device), ")"));
    FrameReport& r = f.report;
    r.stageOne = stageOneReportJson(f.deformation, f.stage1, graphOptionsOf(spec, o), o.ed);
    r.stage1Shape = o.stage1.shape == StageOneShape::Affine ? "affine" : "polar";
    r.inputPath = o.input;
    r.inputFormat = rest.read.format;
    r.inputGaussians = rest.model.size();
    r.inputShDegree = rest.model.shDegree;
    r.inputWarnings = rest.warnings;
    r.specPath = o.specPath;
    r.recipe = o.recipe;
    r.settings = settingsJson(o);
    r.timingsMs["read"] = rest.readMs;
    f.ms = clock.ms();
    return f;
}

void refineFrame(DeformRest& rest, const DeformJobOptions& o, FrameResult& f, const StageTwoStart& start)
{
    if (!rest.grid) throw UsageError("Stage II needs the rest side prepared without --stage1-only");
    Stopwatch clock;
    f.report.timingsMs["sampleGrid"] = rest.sampleGridMs;
    if (rest.validation) f.report.timingsMs["validation"] = rest.validationMs;
    f.fitted =
        runStage("Stage II", [&] { return stageTwo(rest, f.deformation, f.stage1, o, start, f.report, f.stretched); });
    f.ms += clock.ms();
}

FrameReport writeFrame(const DeformRest& rest, const DeformJobOptions& o, const FrameResult& f, const FrameOutputs& out)
{
    Stopwatch clock;
    FrameReport report = f.report;
    double writeMs = 0;
    if (!out.baseline.empty()) {
        writePly(out.baseline, f.stage1.deformed);
        writeMs = clock.ms();
        report.outputs["baseline"] = out.baseline;
    }
    if (f.fitted) {
        if (!out.deformed.empty()) {
            clock.reset();
            writePly(out.deformed, *f.fitted);
            writeMs += clock.ms();
            report.outputs["deformed"] = out.deformed;
        }
        writeExtras(rest, f.stretched, f.stage1.deformed, *f.fitted, o, out, report);
    }
    report.timingsMs["write"] = writeMs;
    report.timingsMs["total"] = f.ms + clock.ms();
    if (!out.report.empty()) writeFileAtomic(out.report, report.toJson().dump(2) + "\n");
    return report;
}

FrameReport runDeformFrame(DeformRest& rest, const DeformSpec& spec, const DeformJobOptions& o, const FrameOutputs& out,
                           GaussianCloud* written, const StageTwoStart& start)
{
    Stopwatch total;
    FrameResult f = poseFrame(rest, spec, o);
    if (!o.stage1Only) refineFrame(rest, o, f, start);
    FrameReport report = writeFrame(rest, o, f, out);
    report.timingsMs["total"] = total.ms();
    if (written) *written = f.fitted ? std::move(*f.fitted) : std::move(f.stage1.deformed);
    return report;
}

FrameReport runDeformJob(const DeformJobOptions& o)
{
    const DeformSpec spec = loadDeformSpec(o.specPath);
    checkDeformOutputs(o);
    DeformSession session(o, spec);
    session.pose(spec);
    if (!o.stage1Only) session.refine();
    FrameReport report = session.write(o.outDir);
    progress(msg("wrote ", o.outDir, "/{", o.stage1Only ? "baseline.ply" : "baseline.ply, deformed.ply", ", report.json}"));
    return report;
}

} // namespace splatwarp
