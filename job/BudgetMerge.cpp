#include "job/BudgetMerge.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>

#include "core/Error.h"
#include "core/ParallelFor.h"
#include "core/Polar.h"
#include "core/Progress.h"
#include "field/GaussianMath.h"
#include "job/ValidationResiduals.h"

namespace splatwarp {

namespace {

/// Gaussians of the same rest Gaussian, families of two or more, each in index order.
std::vector<std::vector<std::size_t>> familiesOf(const std::vector<std::int32_t>& parent)
{
    std::vector<std::size_t> order(parent.size());
    std::iota(order.begin(), order.end(), std::size_t(0));
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return parent[a] < parent[b]; });
    std::vector<std::vector<std::size_t>> families;
    for (std::size_t t = 0; t < order.size();) {
        std::size_t end = t + 1;
        while (end < order.size() && parent[order[end]] == parent[order[t]]) ++end;
        if (end - t > 1) families.emplace_back(order.begin() + std::ptrdiff_t(t), order.begin() + std::ptrdiff_t(end));
        t = end;
    }
    return families;
}

std::vector<GaussianRef> refsOf(const GaussianCloud& g, const std::vector<std::size_t>& members)
{
    std::vector<GaussianRef> refs;
    for (std::size_t i : members) refs.push_back({&g, i});
    return refs;
}

constexpr double kMaxMergedAlpha = 0.99; ///< a merged Gaussian's alpha at most (its logit stays finite)

Vec3d meanOf(const GaussianCloud& g, std::size_t i)
{
    const Vec3f m = g.mean(i);
    return {m.x, m.y, m.z};
}

/// A family's members in runs of three along the line their means spread along most (the children
/// of one Gaussian split twice come as three runs of three: its first split's children).
std::vector<std::vector<std::size_t>> runsOfThree(const GaussianCloud& g, const std::vector<std::size_t>& members)
{
    Vec3d centre(0, 0, 0);
    for (std::size_t i : members) centre += meanOf(g, i);
    centre = centre / double(members.size());
    Mat3d spread;
    for (std::size_t i : members) {
        const Vec3d d = meanOf(g, i) - centre;
        for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b) spread.m[a][b] += d[a] * d[b];
    }
    Vec3d lambda;
    Mat3d v;
    symmetricEigen3(spread, lambda, v);
    const Vec3d axis(v.m[0][0], v.m[1][0], v.m[2][0]);
    std::vector<std::size_t> sorted = members;
    const auto along = [&](std::size_t i) { return dot(meanOf(g, i), axis); };
    std::stable_sort(sorted.begin(), sorted.end(), [&](std::size_t a, std::size_t b) { return along(a) < along(b); });
    std::vector<std::vector<std::size_t>> runs;
    for (std::size_t t = 0; t < sorted.size(); t += 3) {
        runs.emplace_back(sorted.begin() + std::ptrdiff_t(t), sorted.begin() + std::ptrdiff_t(std::min(t + 3, sorted.size())));
        std::sort(runs.back().begin(), runs.back().end());
    }
    return runs;
}

/// How far a family is merged: not, into its runs of three, or into one Gaussian.
enum MergeLevel : std::uint8_t { kUnmerged, kRuns, kWhole };

/// One step of one family's merge, ranked by its validation loss per Gaussian it removes.
struct MergeStep {
    std::size_t family;
    MergeLevel level;
    std::size_t removes;
    double perRemoved;
};

/// The steps of family f: whole (loss `whole`), or runs then whole when the runs cost less per
/// Gaussian removed than the rest of the way does (else merging whole at once is the better step).
void addSteps(std::size_t f, std::size_t size, std::size_t runs, double whole, double partial, std::vector<MergeStep>& steps)
{
    if (runs > 1 && runs < size) {
        const double first = partial / double(size - runs), second = (whole - partial) / double(runs - 1);
        if (first <= second) {
            steps.push_back({f, kRuns, size - runs, first});
            steps.push_back({f, kWhole, runs - 1, second});
            return;
        }
    }
    steps.push_back({f, kWhole, size - 1, whole / double(size - 1)});
}

} // namespace

void appendMerged(const GaussianCloud& g, const std::vector<std::size_t>& members, GaussianCloud& out)
{
    double mass = 0;
    Vec3d mean(0, 0, 0);
    for (std::size_t i : members) {
        mass += g.mass(i);
        mean += meanOf(g, i) * g.mass(i);
    }
    const bool massless = !(mass > 0);
    mean = massless ? meanOf(g, members[0]) : mean / mass;
    Mat3d cov;
    std::vector<double> sh(std::size_t(g.shStride()), 0.0);
    for (std::size_t i : members) {
        const double w = massless ? 1.0 / double(members.size()) : g.mass(i) / mass;
        const Quatf q = g.rotation(i);
        const Vec3f s = g.scale(i);
        const Mat3d own = gaussianCovariance(Quatd{q.w, q.x, q.y, q.z}, Vec3d(s.x, s.y, s.z));
        const Vec3d d = meanOf(g, i) - mean;
        for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b) cov.m[a][b] += w * (own.m[a][b] + d[a] * d[b]);
        const float* c = g.shOf(i);
        for (std::size_t k = 0; k < sh.size(); ++k) sh[k] += w * double(c[k]);
    }
    Vec3d lambda;
    Mat3d v;
    symmetricEigen3(cov, lambda, v);
    const Vec3d sigma(std::sqrt(std::max(lambda.x, 1e-30)), std::sqrt(std::max(lambda.y, 1e-30)),
                      std::sqrt(std::max(lambda.z, 1e-30)));
    const double alpha = massless ? 0.0 : std::min(kMaxMergedAlpha, mass / (sigma.x * sigma.y * sigma.z));
    out.append(g, members[0]);
    const std::size_t o = out.size() - 1;
    out.setMean(o, Vec3f(float(mean.x), float(mean.y), float(mean.z)));
    const Quatd q = matrixToQuat(v);
    out.setRotation(o, Quatf{float(q.w), float(q.x), float(q.y), float(q.z)});
    for (int a = 0; a < 3; ++a) out.logScales[3 * o + std::size_t(a)] = float(std::log(sigma[a]));
    out.opacities[o] = alpha > 0 ? float(std::log(alpha) - std::log1p(-alpha)) : g.opacities[members[0]];
    std::copy(sh.begin(), sh.end(), out.shOf(o));
}

std::vector<std::vector<std::size_t>> groupsToMerge(const Judge& validation, const GaussianCloud& model,
                                                      const std::vector<std::int32_t>& parent, std::size_t limit,
                                                      BudgetMergeReport& report)
{
    const Stopwatch clock;
    if (parent.size() != model.size())
        throw std::logic_error(msg("groupsToMerge: ", parent.size(), " parents for ", model.size(), " Gaussians"));
    report.limit = limit;
    const std::vector<std::vector<std::size_t>> families = familiesOf(parent);
    report.families = families.size();
    if (model.size() <= limit) return {};
    std::size_t removable = 0;
    for (const auto& f : families) removable += f.size() - 1;
    if (model.size() - removable > limit)
        throw UsageError(msg("the Gaussian budget ", limit, " is below the ", model.size() - removable,
                             " Gaussians left with every split merged back"));
    // Each family merged whole (row f of `whole`) and in runs of three (rows runStart[f]... of `parts`).
    GaussianCloud whole, parts;
    whole.shDegree = parts.shDegree = model.shDegree;
    std::vector<std::vector<std::vector<std::size_t>>> runs(families.size());
    std::vector<std::size_t> runStart(families.size());
    for (std::size_t f = 0; f < families.size(); ++f) {
        appendMerged(model, families[f], whole);
        runStart[f] = parts.size();
        if (families[f].size() > 3) runs[f] = runsOfThree(model, families[f]);
        for (const auto& run : runs[f]) appendMerged(model, run, parts);
    }
    const ValidationResiduals residuals(validation, model);
    report.before = residuals.score();
    std::vector<std::vector<MergeStep>> stepsOf(families.size());
    parallelFor(families.size(), 64, validation.points().features.threaded, [&](std::size_t f) {
        std::vector<std::vector<GaussianRef>> in{{{&whole, f}}}; // whole, then (when made) the runs
        if (!runs[f].empty()) {
            in.emplace_back();
            for (std::size_t r = 0; r < runs[f].size(); ++r) in.back().push_back({&parts, runStart[f] + r});
        }
        double loss[2] = {0, 0};
        residuals.changes(refsOf(model, families[f]), in, loss);
        addSteps(f, families[f].size(), runs[f].size(), loss[0], loss[1], stepsOf[f]);
    });
    std::vector<MergeStep> steps;
    for (const auto& s : stepsOf) steps.insert(steps.end(), s.begin(), s.end());
    std::stable_sort(steps.begin(), steps.end(), [](const MergeStep& a, const MergeStep& b) { return a.perRemoved < b.perRemoved; });
    std::vector<MergeLevel> level(families.size(), kUnmerged);
    for (std::size_t count = model.size(), t = 0; count > limit; ++t) {
        level[steps[t].family] = std::max(level[steps[t].family], steps[t].level);
        count -= steps[t].removes;
        report.removed += steps[t].removes;
    }
    std::vector<std::vector<std::size_t>> groups;
    for (std::size_t f = 0; f < families.size(); ++f) {
        if (level[f] == kWhole) groups.push_back(families[f]);
        if (level[f] == kRuns)
            for (const auto& run : runs[f])
                if (run.size() > 1) groups.push_back(run);
        report.merged += level[f] == kWhole;
        report.mergedToRuns += level[f] == kRuns;
    }
    report.ms = clock.ms();
    return groups;
}

GaussianCloud withGroupsMerged(const GaussianCloud& g, const std::vector<std::vector<std::size_t>>& groups)
{
    GaussianCloud out = g, merged;
    merged.shDegree = g.shDegree;
    std::vector<std::uint8_t> drop(g.size(), 0);
    for (std::size_t t = 0; t < groups.size(); ++t) {
        appendMerged(g, groups[t], merged);
        out.assign(groups[t][0], merged, t);
        for (std::size_t k = 1; k < groups[t].size(); ++k) drop[groups[t][k]] = 1;
    }
    out.erase(drop);
    return out;
}

GaussianCloud mergeToBudget(const Judge& validation, const GaussianCloud& model, const std::vector<std::int32_t>& parent,
                            std::size_t limit, BudgetMergeReport& report)
{
    const Stopwatch clock;
    const std::vector<std::vector<std::size_t>> groups = groupsToMerge(validation, model, parent, limit, report);
    if (groups.empty()) {
        report.ms = clock.ms();
        return model;
    }
    GaussianCloud out = withGroupsMerged(model, groups);
    report.after = ValidationResiduals(validation, out).score();
    report.ms = clock.ms();
    return out;
}

} // namespace splatwarp
