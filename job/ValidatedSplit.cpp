#include "job/ValidatedSplit.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "job/ValidationResiduals.h"
#include "core/ParallelFor.h"
#include "core/Progress.h"
#include "deform/CurveSplit.h"

namespace splatwarp {

namespace {

/// The Gaussians that may split: moving, still Stage I's, the heaviest (alpha s0 s1 s2), heaviest first.
std::vector<std::size_t> splittable(const GaussianCloud& rest, const GaussianCloud& stage1, const FitState& s)
{
    std::vector<std::size_t> out;
    std::vector<double> mass(rest.size(), 0.0);
    for (std::size_t i = 0; i < rest.size() && i < s.cloud.size(); ++i) {
        if (!s.moving[i] || !s.cloud.sameGaussian(i, stage1, i)) continue;
        mass[i] = rest.mass(i);
        out.push_back(i);
    }
    std::stable_sort(out.begin(), out.end(), [&](std::size_t a, std::size_t b) { return mass[a] > mass[b]; });
    if (out.size() > kValidatedSplitMaxTried) out.resize(kValidatedSplitMaxTried);
    return out;
}

/// The three children of candidate c along axis a in `moved` (3 per axis, 9 per candidate).
std::vector<GaussianRef> childrenOf(const GaussianCloud& moved, std::size_t c, int a)
{
    const std::size_t base = 3 * (3 * c + std::size_t(a));
    return {{&moved, base}, {&moved, base + 1}, {&moved, base + 2}};
}

} // namespace

ValidatedSplitReport validatedSplit(const Judge& validation, const GaussianCloud& rest, const Deformation& deformation,
                                    const StageOneOptions& stage1, const GaussianCloud& stage1Deformed,
                                    std::size_t budget, FitState s)
{
    const Stopwatch clock;
    ValidatedSplitReport r;
    const std::vector<std::size_t> candidates = budget < 2 ? std::vector<std::size_t>() : splittable(rest, stage1Deformed, s);
    r.tried = candidates.size();
    if (candidates.empty()) { // nothing to try: no score either
        r.ms = clock.ms();
        return r;
    }
    ValidationResiduals residuals(validation, s.cloud);
    r.before = r.after = residuals.score();
    // Every candidate split along each axis, in the rest pose, then moved by Stage I.
    GaussianCloud childRest;
    childRest.shDegree = rest.shDegree;
    const SplitPattern three = curveSplitPattern(0.0, 0.0);
    for (std::size_t i : candidates)
        for (int a = 0; a < 3; ++a) appendSplitChildren(rest, i, a, three, childRest);
    const StageOneRig rig = prepareStageOne(childRest, deformation.graph, stage1);
    const StageOneResult moved = applyStageOneCpu(childRest, rig, deformation.graph, deformation.transforms,
                                                  deformation.nodeMoving, stage1);
    std::vector<float> childCurve;
    if (s.curve && !s.curve->empty())
        childCurve = stageOneBendingOf(childRest, rig, deformation.graph, deformation.transforms, moved.deformed,
                                       moved.moving, stage1).curve;

    // The best axis of each, on the start's residuals; then the largest drops first, re-measured.
    std::vector<double> gain(candidates.size(), 0.0);
    parallelFor(candidates.size(), 16, stage1.threaded, [&](std::size_t c) {
        for (int a = 0; a < 3; ++a)
            gain[c] = std::min(gain[c], residuals.change({{&s.cloud, candidates[c]}}, childrenOf(moved.deformed, c, a)));
    });
    std::vector<std::size_t> order(candidates.size());
    std::iota(order.begin(), order.end(), std::size_t(0));
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return gain[a] < gain[b]; });
    const double minGain = kValidatedSplitMinGain * r.before;
    for (std::size_t c : order) {
        if (!(gain[c] < -minGain) || budget < 2) break;
        const std::size_t i = candidates[c];
        int best = -1;
        double bestChange = -minGain;
        for (int a = 0; a < 3; ++a) {
            const double d = residuals.change({{&s.cloud, i}}, childrenOf(moved.deformed, c, a));
            if (d < bestChange) {
                bestChange = d;
                best = a;
            }
        }
        if (best < 0) continue;
        const std::vector<GaussianRef> children = childrenOf(moved.deformed, c, best);
        residuals.apply({{&s.cloud, i}}, children);
        std::vector<std::size_t> rows;
        for (const GaussianRef& child : children) rows.push_back(child.index);
        s.replace(i, moved.deformed, rows, moved.moving.data(), childCurve.empty() ? nullptr : childCurve.data());
        budget -= children.size() - 1;
        ++r.split;
        r.added += children.size() - 1;
    }
    r.after = residuals.score();
    r.ms = clock.ms();
    progress(msg("validated split: ", r.split, " of ", r.tried, " Gaussians split, ", r.added, " added, validation ", r.before,
                 " -> ", r.after, " (", int(r.ms), " ms)"));
    return r;
}

} // namespace splatwarp
