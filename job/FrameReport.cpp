#include "job/FrameReport.h"

#include <cctype>
#include <cmath>

#include "core/Error.h"
#include "job/HeldOutEval.h"

namespace splatwarp {

namespace {

using json = nlohmann::json;

json curveSplitJson(const CurveSplitRecord& r)
{
    json j = {{"fans", r.fans ? "on" : "off (validated)"}, {"maxAdded", r.options.maxAdded}, {"rounds", r.options.rounds},
              {"fanAbove", r.options.fanAbove}, {"roundsUsed", r.roundsUsed}, {"split", r.split}, {"added", r.added},
              {"pruned", r.pruned}, {"pruneWorth", r.options.pruneWorth}, {"gaussians", r.gaussians}, {"ms", r.ms}};
    if (r.validationWithFans) j["validationWithFans"] = *r.validationWithFans;
    if (r.validationWithoutFans) j["validationWithoutFans"] = *r.validationWithoutFans;
    if (r.errors) modelErrorsJson(*r.errors, j);
    return j;
}

json validatedSplitJson(const ValidatedSplitRecord& r)
{
    return {{"tried", r.result.tried}, {"split", r.result.split}, {"added", r.result.added}, {"budget", r.budget},
            {"validationBefore", r.result.before}, {"validationAfter", r.result.after}, {"ms", r.result.ms}};
}

json curveShiftJson(const CurveShiftRecord& r)
{
    json j = {{"share", r.share}, {"auto", r.automatic}, {"ms", r.ms}};
    for (std::size_t i = 0; i < r.shares.size(); ++i) j["validation"][msg(r.shares[i])] = r.scores[i];
    if (r.errors) modelErrorsJson(*r.errors, j);
    return j;
}

json keepJson(const KeepRecord& r)
{
    const StageTwoChoice& c = r.choice;
    json k = {{"kept", c.kept}, {"regions", c.regions}, {"ms", c.ms}};
    if (std::isfinite(c.mix)) k.update({{"validationMix", c.mix}, {"mixOf", c.mixOf}});
    for (std::size_t i = 0; i < r.candidates.size(); ++i) {
        std::string name = r.candidates[i];
        name[0] = char(std::toupper(name[0]));
        k["validation" + name] = c.scores[i];
        k["regions" + name] = c.regionsWon[i];
    }
    if (const auto& g = r.perGaussian)
        k["perGaussian"] = {{"swapped", g->swapped}, {"tried", g->tried}, {"held", g->held}, {"validationBefore", g->before},
                            {"validationAfter", g->after}, {"ms", g->ms}};
    return k;
}

json energiesJson(const std::vector<StageTwoEnergy>& energies)
{
    json j = json::array();
    for (const StageTwoEnergy& e : energies)
        j.push_back({{"iteration", e.iteration}, {"total", e.total}, {"color", e.color}, {"opacity", e.opacity},
                     {"boundary", e.boundary}, {"rejected", e.rejected}});
    return j;
}

/// The validation stop's checks (StageTwoReport::heldOutChecks).
json checksJson(const std::vector<std::pair<int, double>>& checks)
{
    json out = json::array();
    for (const auto& [iteration, score] : checks) out.push_back({{"iteration", iteration}, {"score", score}});
    return out;
}

/// The fit's own part of "stage2": its energies, grid, throughput, stop and settings.
json fitJson(const StageTwoRecord& s)
{
    const StageTwoReport& r = s.fit;
    const StageTwoOptions& o = s.options;
    std::uint64_t pairs = 0;
    for (std::uint64_t p : r.pairsPerIteration) pairs += p;
    const double pairsPerIteration = r.pairsPerIteration.empty() ? 0.0 : double(pairs) / r.pairsPerIteration.size();
    json roundDevices = json::array();
    for (const Device d : r.roundDevices) roundDevices.push_back(deviceName(d));
    return {{"energies", energiesJson(r.energies)},
            {"roundDevices", roundDevices},
            {"movingGaussians", r.movingGaussians},
            {"activeCells", s.grid.cells},
            {"samplesPerCell", s.gridOptions.samplesPerAxis},
            {"skippedCells", s.grid.skippedCells},
            {"samples", s.grid.samples},
            {"fineCells", s.grid.fineCells},
            {"fineSamplesAdded", s.grid.fineSamplesAdded},
            {"samplesUsed", r.samplesUsed},
            {"pairsPerIteration", pairsPerIteration},
            {"pairsPerSecond", r.msForward + r.msBackward > 0 ? pairs / ((r.msForward + r.msBackward) / 1000.0) : 0.0},
            {"coverageRebuilds", r.coverageRebuilds},
            {"bestIteration", r.bestIteration},
            {"bestEnergy", r.bestEnergy},
            {"rejectedSteps", r.rejectedSteps},
            {"stoppedAt", r.stoppedAt},
            {"stopReason", r.stoppedAt >= 0 ? r.stopReason : std::string("ran every iteration")},
            {"validationChecks", checksJson(r.heldOutChecks)},
            {"device", devicesName(r)},
            {"gpuPeakBytes", r.gpuPeakBytes},
            {"sceneExtent", r.sceneExtent},
            {"parameters",
             {{"iterations", o.iterations}, {"lambdaOpacity", o.lambdaOpacity}, {"boundaryWeight", o.boundaryWeight},
              {"lowPassFilter", o.lowPassFilter}, {"lambdaLpf", o.lambdaLpf}, {"coverageSteps", o.coverageSteps},
              {"rebuildEvery", o.rebuildEvery}, {"cutoff", o.cutoff}, {"rejectSteps", o.rejectSteps},
              {"stallStop", o.stallStop}, {"keepBest", o.keepBest}, {"fineBelow", s.gridOptions.fineBelow},
              {"fineNeighbours", s.gridOptions.fineNeighbours}}},
            {"timingsMs",
             {{"setup", r.msSetup}, {"coverage", r.msCoverage}, {"forward", r.msForward}, {"backward", r.msBackward},
              {"update", r.msUpdate}, {"rejected", r.msRejected}, {"total", r.msTotal}}}};
}

json stageTwoJson(const StageTwoRecord& s)
{
    json j;
    if (s.skipped) {
        j = {{"skipped", "rigid spec"}, {"movingGaussians", 0}, {"device", "none"}};
    } else {
        j = fitJson(s);
        const DensifyJobOptions& d = s.densify;
        j["densify"] = {{"split", d.split ? "auto" : "off"}, {"splitStretch", d.splitStretch}, {"splitAfter", d.splitAfter},
                        {"splitOffset", d.splitOffset},      {"pruneBelow", d.pruneBelow},     {"ms", s.densifyMs}};
    }
    j.update({{"gaussiansAdded", s.gaussiansAdded}, {"gaussiansRemoved", s.gaussiansRemoved}, {"gaussians", s.gaussians}});
    if (s.gaussianBudget) j["gaussianBudget"] = *s.gaussianBudget;
    if (const auto& m = s.budgetMerge)
        j["budgetMerge"] = {{"limit", m->limit},   {"families", m->families},       {"merged", m->merged},
                            {"mergedToRuns", m->mergedToRuns}, {"removed", m->removed}, {"validationBefore", m->before},
                            {"validationAfter", m->after}, {"ms", m->ms}};
    if (s.keep) j["keep"] = keepJson(*s.keep);
    if (s.start) j["start"] = *s.start;
    if (s.warmEnergy) j["warmEnergy"] = *s.warmEnergy;
    if (s.warmLimit) j["warmLimit"] = *s.warmLimit;
    if (s.evalCurve) {
        json curve = json::array();
        for (const CurvePoint& p : *s.evalCurve) {
            json e = fieldErrorJson(p.error);
            e["iteration"] = p.iteration;
            curve.push_back(e);
        }
        j["evalCurve"] = curve;
    }
    if (s.errors) modelErrorsJson(*s.errors, j);
    return j;
}

} // namespace

void modelErrorsJson(const ModelErrors& errors, nlohmann::json& stage)
{
    stage["fieldError"] = judgeJson(errors.judge);
    stage["latticeError"] = fieldErrorJson(errors.lattice);
    stage["latticeError"]["filterVariance"] = errors.latticeFilterVariance;
}

nlohmann::json FrameReport::toJson() const
{
    json j = stageOne;
    j["stage1"]["shape"] = stage1Shape;
    if (stage1Errors) modelErrorsJson(*stage1Errors, j["stage1"]);
    j["input"] = {{"path", inputPath}, {"format", inputFormat}, {"gaussians", inputGaussians}, {"shDegree", inputShDegree}};
    j["input"]["warnings"] = json::array();
    for (const CloudWarning& w : inputWarnings)
        j["input"]["warnings"].push_back({{"kind", w.kind}, {"count", w.count}, {"message", w.message}});
    j["spec"] = specPath;
    if (!recipe.is_null()) j["recipe"] = recipe;
    if (!settings.is_null()) j["settings"] = settings;
    if (warpDevice) j["warpDevice"] = *warpDevice;
    if (curveSplit) j["curveSplit"] = curveSplitJson(*curveSplit);
    if (validatedSplit) j["validatedSplit"] = validatedSplitJson(*validatedSplit);
    if (curveShift) j["curveShift"] = curveShiftJson(*curveShift);
    if (stage2) j["stage2"] = stageTwoJson(*stage2);
    if (stretched) {
        const Vec3d& c = stretched->centre;
        j["stretched"] = {{"cell", stretched->cell}, {"stretch", stretched->stretch}, {"centre", {c.x, c.y, c.z}},
                          {"radius", stretched->radius}};
    }
    for (const auto& [kind, path] : outputs) j["outputs"][kind] = path;
    for (const auto& [step, ms] : timingsMs) j["timingsMs"][step] = ms;
    return j;
}

} // namespace splatwarp
