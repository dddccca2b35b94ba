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

/// Row j of `from` into row i of `to` (same SH degree).
void copyRow(GaussianCloud& to, std::size_t i, const GaussianCloud& from, std::size_t j)
{
    auto copy = [&](std::vector<float>& dst, const std::vector<float>& src, std::size_t width) {
        std::copy_n(src.begin() + std::ptrdiff_t(width * j), width, dst.begin() + std::ptrdiff_t(width * i));
    };
    copy(to.means, from.means, 3);
    copy(to.rotations, from.rotations, 4);
    copy(to.logScales, from.logScales, 3);
    copy(to.opacities, from.opacities, 1);
    copy(to.sh, from.sh, std::size_t(from.shStride()));
}

/// logit(w alpha) for alpha = sigmoid(logit), w in (0, 1].
float scaledLogit(float logit, double w)
{
    const double a = w / (1.0 + std::exp(-double(logit)));
    return a > 0 ? float(std::log(a) - std::log1p(-a)) : float(double(logit) + std::log(w));
}

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
    return std::erf(std::sqrt(0.5 * x)) - std::sqrt(2.0 * x / 3.14159265358979323846) * std::exp(-0.5 * x);
}

/// What a split of Gaussian i bent by m is expected to save, in units of mass alpha s0 s1 s2: its
/// visible mass times the drop of displacedL1 as the children's bend halves, less the visible
/// mass the dimmer children lose to the cutoff and their 1.2% L1 distance from the parent. Near
/// zero or negative for Gaussians far too bent for one split, too faint, or too thin to weigh.
double splitGain(const GaussianCloud& g, std::size_t i, double m)
{
    const Vec3f s = g.scale(i);
    const double alpha = g.alpha(i), mass = alpha * double(s.x) * double(s.y) * double(s.z);
    const double parent = visibleMass(alpha);
    const double children = kCurveChildSigma * (kCurveCentreWeight * visibleMass(kCurveCentreWeight * alpha) +
                                                2.0 * kCurveOuterWeight * visibleMass(kCurveOuterWeight * alpha));
    return mass * (parent * (displacedL1(m) - displacedL1(0.5 * m)) - std::fabs(parent - children) - kCurveSplitL1);
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

void appendCurveChildren(const GaussianCloud& g, std::size_t i, int axis, GaussianCloud& out)
{
    const Mat3f r = quatToMatrix(g.rotation(i));
    const float sigma = g.scale(i)[axis];
    const Vec3f u{r.m[0][axis], r.m[1][axis], r.m[2][axis]};
    const Vec3f m = g.mean(i);
    const float offsets[3] = {0.0f, float(kCurveOffset), -float(kCurveOffset)};
    for (int c = 0; c < 3; ++c) {
        out.append(g, i);
        const std::size_t j = out.size() - 1;
        const float d = offsets[c] * sigma;
        out.setMean(j, Vec3f{m.x + d * u.x, m.y + d * u.y, m.z + d * u.z});
        out.logScales[3 * j + std::size_t(axis)] += float(std::log(kCurveChildSigma));
        out.opacities[j] = scaledLogit(g.opacities[i], c == 0 ? kCurveCentreWeight : kCurveOuterWeight);
    }
}

std::vector<float> stageOneBendingOf(const GaussianCloud& rest, const StageOneRig& rig, const DeformationGraph& graph,
                                     const NodeTransforms& transforms, const GaussianCloud& deformed,
                                     const std::vector<std::uint8_t>& moving, const StageOneOptions& o,
                                     std::vector<std::uint8_t>& axis)
{
    const std::size_t n = rest.size();
    if (deformed.size() != n || moving.size() != n || rig.size() != n)
        throw InputError(msg("bending: ", n, " rest Gaussians, ", deformed.size(), " deformed, ", moving.size(),
                             " flags, a rig of ", rig.size()));
    const std::vector<NodeAffine> affines = nodeAffines(graph, transforms);
    const StageOneInputs in = stageOneInputs(rest, rig, affines.data());
    const StageOneParams params = stageOneParams(o, rig.extent);
    std::vector<float> bending(n, 0.0f);
    axis.assign(n, 0);
    parallelFor(n, 256, o.threaded, [&](std::size_t i) {
        if (!moving[i]) return;
        const Vec3d b = stageOneBending(in, params, i, deformed.rotations.data() + 4 * i, deformed.logScales.data() + 3 * i);
        int a = 0;
        for (int c = 1; c < 3; ++c)
            if (b[c] > b[a]) a = c;
        bending[i] = float(b[a]);
        axis[i] = std::uint8_t(a);
    });
    return bending;
}

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
    std::size_t budget = std::size_t(double(o.maxAdded) * double(rest.size()));
    StageOneOptions childOptions = s1;
    childOptions.threaded = o.threaded;

    Generation gen{rest, rig, stage1, {}};
    gen.slot.resize(rest.size());
    std::iota(gen.slot.begin(), gen.slot.end(), std::size_t(0));
    for (int round = 0; round < o.rounds && budget >= 2; ++round) {
        std::vector<std::uint8_t> axis;
        const std::vector<float> bending = stageOneBendingOf(gen.rest, gen.rig, graph, transforms, gen.stage1.deformed,
                                                             gen.stage1.moving, childOptions, axis);
        std::vector<std::size_t> bent;
        std::vector<double> gain(bending.size(), 0.0);
        for (std::size_t i = 0; i < bending.size(); ++i) {
            if (!(bending[i] > 0.0f)) continue;
            gain[i] = splitGain(gen.rest, i, bending[i]);
            if (gain[i] > 0) bent.push_back(i);
        }
        if (bent.empty()) break;
        std::stable_sort(bent.begin(), bent.end(), [&](std::size_t a, std::size_t b) { return gain[a] > gain[b]; });
        bent.resize(std::min(bent.size(), budget / 2));
        budget -= 2 * bent.size();

        Generation next;
        next.rest.shDegree = rest.shDegree;
        for (std::size_t i : bent) appendCurveChildren(gen.rest, i, axis[i], next.rest);
        next.rig = prepareStageOne(next.rest, graph, childOptions);
        next.stage1 = applyStageOneCpu(next.rest, next.rig, graph, transforms, nodeMoving, childOptions);
        next.slot.resize(next.rest.size());
        for (std::size_t c = 0; c < bent.size(); ++c) {
            const std::size_t parentSlot = gen.slot[bent[c]];
            const std::int32_t origin = res.parent[parentSlot];
            for (std::size_t k = 0; k < 3; ++k) {
                const std::size_t child = 3 * c + k;
                std::size_t slot = parentSlot;
                if (k > 0) {
                    res.deformed.append(next.stage1.deformed, child);
                    res.moving.push_back(0);
                    res.parent.push_back(origin);
                    slot = res.deformed.size() - 1;
                } else {
                    copyRow(res.deformed, slot, next.stage1.deformed, child);
                }
                res.moving[slot] = next.stage1.moving[child];
                next.slot[child] = slot;
            }
        }
        res.split += bent.size();
        res.added += 2 * bent.size();
        res.rounds = round + 1;
        progress(msg("curve split round ", round + 1, ": ", bent.size(), " bent Gaussians split in three (largest bend ",
                     bending[bent.front()], " sigmas)"));
        gen = std::move(next);
    }
    res.ms = clock.ms();
    return res;
}

} // namespace splatwarp
