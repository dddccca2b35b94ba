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
    const double alpha = g.alpha(i), mass = g.mass(i);
    const double parent = visibleMass(alpha);
    double children = 0.0;
    for (double w : p.weights) children += p.sigma * w * visibleMass(w * alpha);
    const double saved = parent * (displacedL1(m) - displacedL1(m * p.sigma * p.sigma));
    return mass * (saved - std::fabs(parent - children) - kCurveSplitL1) / double(p.offsets.size() - 1);
}

/// Gaussian i's mean projected area, up to a constant factor: s0 s1 + s1 s2 + s0 s2.
double meanArea(const GaussianCloud& g, std::size_t i)
{
    const Vec3f s = g.scale(i);
    return double(s.x) * s.y + double(s.y) * s.z + double(s.x) * s.z;
}

/// Gaussian i's mean projected area over its volume: what turns splitGain()'s mass units into a
/// view's (alpha times area). A flat Gaussian of a surface holds little mass and covers much.
double areaPerVolume(const GaussianCloud& g, std::size_t i)
{
    const Vec3f s = g.scale(i);
    return meanArea(g, i) / (double(s.x) * s.y * s.z);
}

/// What removing Gaussian i of a model costs a view: its visible alpha times its mean projected area.
double pruneCost(const GaussianCloud& g, std::size_t i)
{
    const double alpha = g.alpha(i);
    return alpha * visibleMass(alpha) * meanArea(g, i);
}

/// The model's own Gaussians (the result's first slots) that may make room for children, faintest
/// first: a split whose gain per Gaussian added exceeds worth x a Gaussian's cost may remove it.
class Pruner {
public:
    Pruner(const GaussianCloud& model, double worth) : worth_(worth), removed_(model.size(), 0), split_(model.size(), 0)
    {
        if (!(worth > 0)) return;
        cost_.resize(model.size());
        for (std::size_t i = 0; i < model.size(); ++i) cost_[i] = pruneCost(model, i);
        order_.resize(model.size());
        std::iota(order_.begin(), order_.end(), std::size_t(0));
        std::stable_sort(order_.begin(), order_.end(), [&](std::size_t a, std::size_t b) { return cost_[a] < cost_[b]; });
    }
    /// A Gaussian in this slot is split: it is no longer a candidate (children's slots are past the model's).
    void markSplit(std::size_t slot)
    {
        if (slot < split_.size()) split_[slot] = 1;
    }
    bool removed(std::size_t slot) const { return slot < removed_.size() && removed_[slot]; }
    /// Removes `count` Gaussians for a split of this gain per Gaussian added, when each costs less;
    /// false (nothing removed) otherwise.
    bool makeRoom(std::size_t count, double gain, std::size_t skipSlot)
    {
        std::vector<std::size_t> picked;
        for (std::size_t k = next_; k < order_.size() && picked.size() < count; ++k) {
            const std::size_t i = order_[k];
            if (removed_[i] || split_[i] || i == skipSlot) continue;
            if (!(worth_ * cost_[i] < gain)) break;
            picked.push_back(i);
        }
        if (picked.size() < count) return false;
        for (std::size_t i : picked) removed_[i] = 1;
        while (next_ < order_.size() && (removed_[order_[next_]] || split_[order_[next_]])) ++next_;
        count_ += count;
        return true;
    }
    std::size_t count() const { return count_; }

private:
    double worth_;
    std::vector<double> cost_;
    std::vector<std::size_t> order_;
    std::vector<std::uint8_t> removed_, split_;
    std::size_t next_ = 0, count_ = 0;
};

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

/// The Gaussians of a generation worth splitting (bend > 0, positive gain), most gain first;
/// `gain` receives each one's gain per Gaussian added.
std::vector<std::size_t> bentByGain(const GaussianCloud& rest, const std::vector<float>& bending, double fanAbove,
                                    std::vector<double>& gain)
{
    std::vector<std::size_t> bent;
    gain.assign(bending.size(), 0.0);
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

/// The result without the Gaussians the pruner removed.
void removePruned(const Pruner& pruner, CurveSplitResult& res)
{
    std::vector<std::uint8_t> drop(res.parent.size(), 0);
    for (std::size_t j = 0; j < drop.size(); ++j) drop[j] = pruner.removed(j);
    res.deformed.erase(drop);
    eraseRows(res.moving, drop);
    eraseRows(res.parent, drop);
    eraseRows(res.curve, drop, 3);
    res.pruned = pruner.count();
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
    Pruner pruner(stage1.deformed, o.pruneWorth);

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
    for (int round = 0; round < o.rounds && (budget >= 2 || o.pruneWorth > 0); ++round) {
        measure();
        const std::vector<float>& bending = bends.bend;
        std::vector<double> gain;
        std::vector<std::size_t> bent = bentByGain(gen.rest, bending, o.fanAbove, gain);
        if (o.fanAbove > 0.0)
            res.beyondFan += std::size_t(std::count_if(bending.begin(), bending.end(), [&](float b) { return b > o.fanAbove; }));
        if (bent.empty()) break;
        Generation next;
        next.rest.shDegree = rest.shDegree;
        std::vector<std::size_t> counts, taken; // children per split, in the order of next.rest
        for (std::size_t i : bent) {
            const SplitPattern p = curveSplitPattern(bending[i], o.fanAbove);
            const std::size_t need = p.offsets.size() - 1, slot = gen.slot[i];
            if (pruner.removed(slot)) continue;
            if (need > budget) {
                if (!pruner.makeRoom(need - budget, gain[i] * areaPerVolume(gen.rest, i), slot)) continue; // a smaller split may still fit
                budget = need;
            }
            budget -= need;
            pruner.markSplit(slot);
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
    if (pruner.count()) removePruned(pruner, res);
    res.ms = clock.ms();
    return res;
}

} // namespace splatwarp
