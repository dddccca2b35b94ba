#include "deform/StageOne.h"

#include <algorithm>
#include <cmath>

#include "core/Error.h"
#include "core/ParallelFor.h"
#include "core/Progress.h"
#include "deform/StageOneMath.h"

namespace splatwarp {

namespace {

constexpr std::size_t kPoints = kStageOnePoints;

} // namespace

StageOneParams stageOneParams(const StageOneOptions& o, double extent)
{
    StageOneParams p;
    p.endpointSigmas = o.endpointSigmas;
    p.flatEpsilon = o.flatEpsilon;
    p.absoluteEpsilon = o.absoluteEpsilon;
    p.minStretch = o.minStretch;
    p.extent = extent;
    p.affineShape = o.shape == StageOneShape::Affine;
    return p;
}

void checkStageOneInputs(const GaussianCloud& rest, const StageOneRig& rig, const DeformationGraph& graph,
                         const NodeTransforms& transforms, const std::vector<std::uint8_t>& nodeMoving)
{
    const std::size_t n = rest.size();
    if (rig.size() != n || rig.weights.size() != n * kPoints)
        throw InputError(msg("Stage I rig is for ", rig.size(), " Gaussians, the model has ", n));
    if (transforms.size() != graph.nodeCount() || nodeMoving.size() != graph.nodeCount())
        throw InputError(msg("Stage I: ", transforms.size(), " transforms / ", nodeMoving.size(),
                             " moving flags for a graph of ", graph.nodeCount(), " nodes"));
}

StageOneInputs stageOneInputs(const GaussianCloud& rest, const StageOneRig& rig, const NodeAffine* affines)
{
    StageOneInputs in;
    in.means = rest.means.data();
    in.rotations = rest.rotations.data();
    in.logScales = rest.logScales.data();
    in.nodes = rig.weights.nodes.data();
    in.weights = rig.weights.weights.data();
    in.k = std::size_t(rig.weights.k);
    in.affines = affines;
    return in;
}

StageOneRig prepareStageOne(const GaussianCloud& rest, const DeformationGraph& graph, const StageOneOptions& o)
{
    rest.checkConsistent();
    StageOneRig rig;
    const std::size_t n = rest.size();
    Vec3f lo, hi;
    centreBounds(rest, lo, hi);
    rig.extent = std::max({double(hi.x - lo.x), double(hi.y - lo.y), double(hi.z - lo.z)});
    if (!(rig.extent > 0.0)) rig.extent = 1.0;
    rig.points.resize(n * kPoints * 3);
    const StageOneParams params = stageOneParams(o, rig.extent);
    parallelFor(n, 1024, o.threaded, [&](std::size_t i) {
        const StageOneRestFrame f =
            stageOneRestFrame(rest.means.data(), rest.rotations.data(), rest.logScales.data(), i, params);
        float* p = rig.points.data() + i * kPoints * 3;
        for (int a = 0; a < 3; ++a) p[a] = rest.means[3 * i + std::size_t(a)];
        for (int e = 0; e < 6; ++e) {
            const Vec3d q = stageOneEndpoint(f, e, o.endpointSigmas);
            for (int a = 0; a < 3; ++a) p[3 * (e + 1) + a] = float(q[a]);
        }
    });
    rig.weights = graph.skinWeights(rig.points.data(), n * kPoints, o.threaded);
    return rig;
}

namespace {

/// Stage I of every Gaussian into `into` (which holds rest's values where nothing moves); SH bands
/// up to shDegree are rotated (0: none). Returns the moving Gaussians' count.
std::size_t updateInto(const GaussianCloud& rest, const StageOneRig& rig, const DeformationGraph& graph,
                       const NodeTransforms& transforms, const std::vector<std::uint8_t>& nodeMoving,
                       const StageOneOptions& o, int shDegree, GaussianCloud& into, std::vector<std::uint8_t>& moving)
{
    checkStageOneInputs(rest, rig, graph, transforms, nodeMoving);
    const std::size_t n = rest.size();
    moving.assign(n, 0);
    const std::vector<NodeAffine> affines = nodeAffines(graph, transforms);
    StageOneInputs in = stageOneInputs(rest, rig, affines.data());
    in.nodeMoving = nodeMoving.data();
    in.shTables = &shRotationTables();
    in.shDegree = shDegree;
    StageOneOutputs out;
    out.means = into.means.data();
    out.rotations = into.rotations.data();
    out.logScales = into.logScales.data();
    out.sh = into.sh.data();
    out.moving = moving.data();
    const StageOneParams params = stageOneParams(o, rig.extent);
    parallelFor(n, 256, o.threaded, [&](std::size_t i) { stageOneUpdate(in, params, i, out); });
    return std::size_t(std::count(moving.begin(), moving.end(), std::uint8_t(1)));
}

} // namespace

StageOneResult applyStageOneCpu(const GaussianCloud& rest, const StageOneRig& rig, const DeformationGraph& graph,
                             const NodeTransforms& transforms, const std::vector<std::uint8_t>& nodeMoving,
                             const StageOneOptions& o)
{
    const Stopwatch clock;
    StageOneResult res;
    res.deformed = rest; // static Gaussians stay bit-exact
    res.movingCount = updateInto(rest, rig, graph, transforms, nodeMoving, o, rest.shDegree, res.deformed, res.moving);
    res.timings.updateMs = clock.ms();
    return res;
}

} // namespace splatwarp
