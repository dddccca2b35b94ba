#include "deform/StageOne.h"

#include <algorithm>
#include <cmath>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "core/Error.h"
#include "core/Polar.h"
#include "core/Progress.h"
#include "sh/SphericalHarmonics.h"

namespace splatwarp {

namespace {

constexpr std::size_t kPoints = 7; // centre + 6 endpoints

/// Rest frame of Gaussian i: rotation (normalised quaternion) and endpoint sigmas.
struct RestFrame {
    Mat3d r0;
    Vec3d sigma;
    Vec3d centre;
};

RestFrame restFrame(const GaussianCloud& g, std::size_t i, double extent, const StageOneOptions& o)
{
    const Quatf qf = g.rotation(i);
    RestFrame f;
    f.r0 = quatToMatrix(Quatd{qf.w, qf.x, qf.y, qf.z});
    f.centre = Vec3d(g.mean(i));
    const Vec3d s(std::exp(double(g.logScales[3 * i])), std::exp(double(g.logScales[3 * i + 1])),
                  std::exp(double(g.logScales[3 * i + 2])));
    const double eps = std::max(o.flatEpsilon * std::max({s.x, s.y, s.z}), o.absoluteEpsilon * extent);
    f.sigma = Vec3d(s.x + eps, s.y + eps, s.z + eps);
    return f;
}

/// Rest endpoint e (0..5: +x,-x,+y,-y,+z,-z of the Gaussian's own axes).
Vec3d endpoint(const RestFrame& f, int e, double sigmas)
{
    const int a = e / 2;
    const double sign = (e % 2 == 0) ? 1.0 : -1.0;
    const Vec3d axis(f.r0[0][a], f.r0[1][a], f.r0[2][a]);
    return f.centre + axis * (sign * sigmas * f.sigma[a]);
}



} // namespace

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
    auto body = [&](const tbb::blocked_range<std::size_t>& range) {
        for (std::size_t i = range.begin(); i != range.end(); ++i) {
            const RestFrame f = restFrame(rest, i, rig.extent, o);
            float* p = rig.points.data() + i * kPoints * 3;
            for (int a = 0; a < 3; ++a) p[a] = rest.means[3 * i + std::size_t(a)];
            for (int e = 0; e < 6; ++e) {
                const Vec3d q = endpoint(f, e, o.endpointSigmas);
                for (int a = 0; a < 3; ++a) p[3 * (e + 1) + a] = float(q[a]);
            }
        }
    };
    if (o.threaded)
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 1024), body);
    else
        body(tbb::blocked_range<std::size_t>(0, n));
    rig.weights = graph.skinWeights(rig.points.data(), n * kPoints, o.threaded);
    return rig;
}

StageOneResult applyStageOne(const GaussianCloud& rest, const StageOneRig& rig, const DeformationGraph& graph,
                             const NodeTransforms& transforms, const std::vector<std::uint8_t>& nodeMoving,
                             const StageOneOptions& o)
{
    const Stopwatch clock;
    const std::size_t n = rest.size();
    if (rig.size() != n || rig.weights.size() != n * kPoints)
        throw InputError(msg("Stage I rig is for ", rig.size(), " Gaussians, the model has ", n));
    if (transforms.size() != graph.nodeCount() || nodeMoving.size() != graph.nodeCount())
        throw InputError(msg("Stage I: ", transforms.size(), " transforms / ", nodeMoving.size(),
                             " moving flags for a graph of ", graph.nodeCount(), " nodes"));
    StageOneResult res;
    res.deformed = rest; // static Gaussians stay bit-exact
    res.moving.assign(n, 0);
    const std::size_t k = std::size_t(rig.weights.k);
    const int degree = rest.shDegree;
    const AffineSkinning nodes(graph, transforms);
    auto body = [&](const tbb::blocked_range<std::size_t>& range) {
        for (std::size_t i = range.begin(); i != range.end(); ++i) {
            bool moving = false;
            for (std::size_t q = i * kPoints * k; q < (i + 1) * kPoints * k && !moving; ++q)
                moving = rig.weights.weights[q] > 0.0f && nodeMoving[std::size_t(rig.weights.nodes[q])];
            if (!moving) continue;
            res.moving[i] = 1;
            const RestFrame f = restFrame(rest, i, rig.extent, o);
            const std::size_t base = i * kPoints;
            const Vec3d centre = nodes.point(rig.weights, base, f.centre);
            // With Q the symmetric endpoint offsets +-c sigma_a r_a, (P Q^T)(Q Q^T)^-1 reduces to
            // M r_a = (p_a+ - p_a-) / (2 c sigma_a): the same least-squares M without the 3x3 inverse.
            Mat3d mr; // columns M r_a
            for (int a = 0; a < 3; ++a) {
                const Vec3d plus = nodes.point(rig.weights, base + 1 + std::size_t(2 * a), endpoint(f, 2 * a, o.endpointSigmas));
                const Vec3d minus = nodes.point(rig.weights, base + 2 + std::size_t(2 * a), endpoint(f, 2 * a + 1, o.endpointSigmas));
                const Vec3d col = (plus - minus) / (2.0 * o.endpointSigmas * f.sigma[a]);
                for (int r = 0; r < 3; ++r) mr[r][a] = col[r];
            }
            // M = mr R0^T = R S gives mr = (R R0)(R0^T S R0): the polar factors of mr are the
            // deformed frame R R0 directly, and S's stretch along r_a is (R0^T S R0)_aa.
            Mat3d rr0; // R R0
            Vec3d stretch;
            if (polarRotationNewton(mr, rr0)) {
                for (int a = 0; a < 3; ++a)
                    stretch[a] = rr0[0][a] * mr[0][a] + rr0[1][a] * mr[1][a] + rr0[2][a] * mr[2][a];
            } else {
                Mat3d r, s;
                polarDecomposition(mr * f.r0.transposed(), r, s);
                rr0 = r * f.r0;
                for (int a = 0; a < 3; ++a) {
                    const Vec3d ra(f.r0[0][a], f.r0[1][a], f.r0[2][a]);
                    stretch[a] = dot(ra, s * ra);
                }
            }
            const Quatd q = matrixToQuat(rr0);
            res.deformed.setMean(i, Vec3f(centre));
            res.deformed.setRotation(i, Quatf{float(q.w), float(q.x), float(q.y), float(q.z)});
            for (int a = 0; a < 3; ++a)
                res.deformed.logScales[3 * i + std::size_t(a)] =
                    float(double(rest.logScales[3 * i + std::size_t(a)]) + std::log(std::max(stretch[a], o.minStretch)));
            if (degree > 0) ShRotation(rr0 * f.r0.transposed(), degree).apply(degree, res.deformed.shOf(i));
        }
    };
    if (o.threaded)
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 256), body);
    else
        body(tbb::blocked_range<std::size_t>(0, n));
    res.movingCount = std::size_t(std::count(res.moving.begin(), res.moving.end(), std::uint8_t(1)));
    res.timings.updateMs = clock.ms();
    return res;
}

StageOneResult runStageOne(const GaussianCloud& rest, const Deformation& d, const StageOneOptions& o)
{
    const Stopwatch clock;
    const StageOneRig rig = prepareStageOne(rest, d.graph, o);
    const double rigMs = clock.ms();
    StageOneResult res = applyStageOne(rest, rig, d.graph, d.transforms, d.nodeMoving, o);
    res.timings.rigMs = rigMs;
    progress(msg("Stage I: ", res.movingCount, " of ", rest.size(), " Gaussians moved (", int(rigMs), " ms weights, ",
                 int(res.timings.updateMs), " ms update)"));
    return res;
}

} // namespace splatwarp
