#include "deform/CurveSplit.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "core/Error.h"
#include "core/ParallelFor.h"
#include "core/Progress.h"
#include "deform/StageOneMath.h"
#include "field/GaussianMath.h"

namespace splatwarp {

namespace {

/// L1 distance between a unit Gaussian and its copy moved by m sigmas, over its mass: what one
/// Gaussian bent by m of its sigmas roughly costs (0 at m = 0, 2 when the two no longer overlap).
double displacedL1(double m)
{
    return 2.0 * std::erf(m / (2.0 * std::sqrt(2.0)));
}

/// Share of a Gaussian's mass that counts when its peak alpha is `peak`: the field (and a
/// renderer) drops alpha G below the cutoff, i.e. the mass beyond chi^2_3 = 2 ln(peak / cutoff).
double visibleMass(double peak)
{
    if (!(peak > double(kDefaultCutoff))) return 0.0;
    const double x = 2.0 * std::log(peak / double(kDefaultCutoff));
    return std::erf(std::sqrt(0.5 * x)) - std::sqrt(2.0 * x / M_PI) * std::exp(-0.5 * x);
}

/// What splitting Gaussian i (bent by m) by a pattern is expected to save per Gaussian added, in
/// units of mass alpha s0 s1 s2: its visible mass times the drop of displacedL1 as the bend goes
/// from m to m t^2, less the visible mass the dimmer children lose to the cutoff and the split's
/// own L1 (taken as the three's 1.15% for a fan too). Near zero or negative for Gaussians too
/// faint or too thin to weigh.
double splitGain(const GaussianCloud& g, std::size_t i, double m, const SplitPattern& p)
{
    const Vec3f s = g.scale(i);
    const double alpha = g.alpha(i), mass = alpha * double(s.x) * double(s.y) * double(s.z);
    const double parent = visibleMass(alpha);
    double children = 0.0;
    for (double w : p.weights) children += p.sigma * w * visibleMass(w * alpha);
    const double saved = parent * (displacedL1(m) - displacedL1(m * p.sigma * p.sigma));
    return mass * (saved - std::fabs(parent - children) - kCurveSplitL1) / double(p.offsets.size() - 1);
}

/// One generation of Gaussians to check: a rest cloud, its rig and Stage I result, and where each
/// one sits in the output.
struct Generation {
    GaussianCloud rest;
    StageOneRig rig;
    StageOneResult stage1;
    std::vector<std::size_t> slot;
};

} // namespace

SplitPattern curveSplitPattern(double bend, double fanAbove)
{
    SplitPattern p;
    p.sigma = kCurveChildSigma;
    if (!(fanAbove > 0.0 && bend > fanAbove)) {
        p.offsets = {0.0, kCurveOffset, -kCurveOffset};
        p.weights = {kCurveCentreWeight, kCurveOuterWeight, kCurveOuterWeight};
        return p;
    }
    const double t = std::max(kFanMinSigma, std::sqrt(kFanChildBend / bend)), var = 1.0 - t * t, delta = 1.25 * t;
    p.sigma = t;
    const int half = int(std::floor(3.0 * std::sqrt(var) / delta));
    for (int k = 0; k <= 2 * half; ++k) {
        const int j = k == 0 ? 0 : (k % 2 ? (k + 1) / 2 : -(k / 2)); // 0, +1, -1, +2, -2, ...
        const double u = j * delta;
        p.offsets.push_back(u);
        p.weights.push_back(delta / t * std::exp(-0.5 * u * u / var) / std::sqrt(2.0 * M_PI * var));
    }
    return p;
}

StageOneBends stageOneBendingOf(const GaussianCloud& rest, const StageOneRig& rig, const DeformationGraph& graph,
                                const NodeTransforms& transforms, const GaussianCloud& deformed,
                                const std::vector<std::uint8_t>& moving, const StageOneOptions& o)
{
    const std::size_t n = rest.size();
    if (deformed.size() != n || moving.size() != n || rig.size() != n)
        throw InputError(msg("bending: ", n, " rest Gaussians, ", deformed.size(), " deformed, ", moving.size(),
                             " flags, a rig of ", rig.size()));
    const std::vector<NodeAffine> affines = nodeAffines(graph, transforms);
    const StageOneInputs in = stageOneInputs(rest, rig, affines.data());
    const StageOneParams params = stageOneParams(o, rig.extent);
    StageOneBends out{std::vector<float>(n, 0.0f), std::vector<std::uint8_t>(n, 0), std::vector<float>(3 * n, 0.0f)};
    parallelFor(n, 256, o.threaded, [&](std::size_t i) {
        if (!moving[i]) return;
        const StageOneCurvature c = stageOneCurvature(in, params, i);
        const Vec3d b = stageOneBending(c, deformed.rotations.data() + 4 * i, deformed.logScales.data() + 3 * i);
        int a = 0;
        for (int k = 1; k < 3; ++k)
            if (b[k] > b[a]) a = k;
        out.bend[i] = float(b[a]);
        out.axis[i] = std::uint8_t(a);
        const Vec3d sum = c.sum();
        for (int k = 0; k < 3; ++k) out.curve[3 * i + std::size_t(k)] = float(sum[k]);
    });
    return out;
}

GaussianCloud curveShifted(GaussianCloud deformed, const std::vector<float>& curve, double share)
{
    if (curve.size() != deformed.means.size())
        throw InputError(msg("curve shift: ", curve.size() / 3, " offsets for ", deformed.size(), " Gaussians"));
    for (std::size_t j = 0; j < curve.size(); ++j) deformed.means[j] += float(share * double(curve[j]));
    return deformed;
}

namespace {

/// The Gaussians of a generation worth splitting (bend > 0, positive gain), most gain first.
std::vector<std::size_t> bentByGain(const GaussianCloud& rest, const std::vector<float>& bending, double fanAbove)
{
    std::vector<std::size_t> bent;
    std::vector<double> gain(bending.size(), 0.0);
    for (std::size_t i = 0; i < bending.size(); ++i) {
        if (!(bending[i] > 0.0f)) continue;
        gain[i] = splitGain(rest, i, bending[i], curveSplitPattern(bending[i], fanAbove));
        if (gain[i] > 0) bent.push_back(i);
    }
    std::stable_sort(bent.begin(), bent.end(), [&](std::size_t a, std::size_t b) { return gain[a] > gain[b]; });
    return bent;
}

/// Put the moved children of the split Gaussians gen[bent[c]] (counts[c] each, in next's order)
/// into the result: the first takes its parent's slot, the others are appended; next.slot records
/// where each one went.
void placeChildren(const Generation& gen, const std::vector<std::size_t>& bent, const std::vector<std::size_t>& counts,
                   Generation& next, CurveSplitResult& res)
{
    next.slot.resize(next.rest.size());
    std::size_t child = 0;
    for (std::size_t c = 0; c < bent.size(); ++c) {
        const std::size_t parentSlot = gen.slot[bent[c]];
        const std::int32_t origin = res.parent[parentSlot];
        for (std::size_t k = 0; k < counts[c]; ++k, ++child) {
            std::size_t slot = parentSlot;
            if (k > 0) {
                res.deformed.append(next.stage1.deformed, child);
                res.moving.push_back(0);
                res.parent.push_back(origin);
                slot = res.deformed.size() - 1;
            } else {
                res.deformed.assign(slot, next.stage1.deformed, child);
            }
            res.moving[slot] = next.stage1.moving[child];
            next.slot[child] = slot;
        }
    }
}

/// Each Gaussian of a generation's curvature offset into its result slot (res.curve).
void recordCurves(const StageOneBends& bends, const Generation& gen, CurveSplitResult& res)
{
    res.curve.resize(3 * res.deformed.size(), 0.0f);
    for (std::size_t j = 0; j < gen.slot.size(); ++j)
        std::copy_n(bends.curve.begin() + std::ptrdiff_t(3 * j), 3, res.curve.begin() + std::ptrdiff_t(3 * gen.slot[j]));
}

} // namespace

CurveSplitResult curveSplit(const GaussianCloud& rest, const StageOneRig& rig, const DeformationGraph& graph,
                            const NodeTransforms& transforms, const std::vector<std::uint8_t>& nodeMoving,
                            const StageOneResult& stage1, const StageOneOptions& s1, const CurveSplitOptions& o)
{
    const Stopwatch clock;
    CurveSplitResult res;
    res.deformed = stage1.deformed;
    res.moving = stage1.moving;
    res.parent.resize(rest.size());
    std::iota(res.parent.begin(), res.parent.end(), 0);
    std::size_t budget = o.maxAddedCount ? *o.maxAddedCount : std::size_t(double(o.maxAdded) * double(rest.size()));
    StageOneOptions childOptions = s1;
    childOptions.threaded = o.threaded;

    Generation gen{rest, rig, stage1, {}};
    gen.slot.resize(rest.size());
    std::iota(gen.slot.begin(), gen.slot.end(), std::size_t(0));
    bool measured = false; // gen's bends are recorded
    StageOneBends bends;
    auto measure = [&] {
        bends = stageOneBendingOf(gen.rest, gen.rig, graph, transforms, gen.stage1.deformed, gen.stage1.moving,
                                  childOptions);
        recordCurves(bends, gen, res);
        measured = true;
    };
    for (int round = 0; round < o.rounds && budget >= 2; ++round) {
        measure();
        const std::vector<float>& bending = bends.bend;
        std::vector<std::size_t> bent = bentByGain(gen.rest, bending, o.fanAbove);
        if (o.fanAbove > 0.0)
            res.beyondFan += std::size_t(std::count_if(bending.begin(), bending.end(), [&](float b) { return b > o.fanAbove; }));
        if (bent.empty()) break;
        Generation next;
        next.rest.shDegree = rest.shDegree;
        std::vector<std::size_t> counts, taken; // children per split, in the order of next.rest
        for (std::size_t i : bent) {
            const SplitPattern p = curveSplitPattern(bending[i], o.fanAbove);
            if (p.offsets.size() - 1 > budget) continue; // a smaller split may still fit
            budget -= p.offsets.size() - 1;
            counts.push_back(appendSplitChildren(gen.rest, i, bends.axis[i], p, next.rest));
            taken.push_back(i);
        }
        if (taken.empty()) break;
        bent = std::move(taken);
        next.rig = prepareStageOne(next.rest, graph, childOptions);
        next.stage1 = applyStageOneCpu(next.rest, next.rig, graph, transforms, nodeMoving, childOptions);
        placeChildren(gen, bent, counts, next, res);
        const std::size_t added = next.rest.size() - bent.size();
        res.split += bent.size();
        res.added += added;
        res.rounds = round + 1;
        progress(msg("curve split round ", round + 1, ": ", bent.size(), " bent Gaussians split, ", added, " added"));
        gen = std::move(next);
        measured = false;
    }
    if (!measured) measure();
    res.ms = clock.ms();
    return res;
}

} // namespace splatwarp
