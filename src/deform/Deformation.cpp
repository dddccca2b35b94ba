#include "deform/Deformation.h"

#include <algorithm>
#include <cmath>

#include "core/Error.h"
#include "core/Progress.h"

namespace splatwarp {

namespace {

/// Rotation by `degrees` about a unit axis (Rodrigues).
Mat3d axisAngle(const Vec3d& axis, double degrees)
{
    const double a = degrees * M_PI / 180.0, c = std::cos(a), s = std::sin(a), t = 1.0 - c;
    const double x = axis.x, y = axis.y, z = axis.z;
    Mat3d r;
    r.m[0][0] = t * x * x + c;     r.m[0][1] = t * x * y - s * z; r.m[0][2] = t * x * z + s * y;
    r.m[1][0] = t * x * y + s * z; r.m[1][1] = t * y * y + c;     r.m[1][2] = t * y * z - s * x;
    r.m[2][0] = t * x * z - s * y; r.m[2][1] = t * y * z + s * x; r.m[2][2] = t * z * z + c;
    return r;
}

/// Maps spec units to world units.
struct Units {
    Vec3d lo, extent;
    bool bbox = false;
    Vec3d position(const Vec3d& p) const
    {
        return bbox ? Vec3d(lo.x + p.x * extent.x, lo.y + p.y * extent.y, lo.z + p.z * extent.z) : p;
    }
    Vec3d offset(const Vec3d& t) const { return bbox ? Vec3d(t.x * extent.x, t.y * extent.y, t.z * extent.z) : t; }
    double length(double r) const { return bbox ? r * std::max({extent.x, extent.y, extent.z}) : r; }
};

} // namespace

HandleResolution resolveHandles(const DeformSpec& spec, const DeformationGraph& graph, const GaussianCloud& rest)
{
    const std::size_t n = graph.nodeCount();
    const std::vector<Vec3d>& g = graph.nodes();
    Units u;
    u.bbox = spec.units == DeformSpec::Units::Bbox;
    Vec3f lo, hi;
    centreBounds(rest, lo, hi);
    u.lo = Vec3d(lo);
    u.extent = Vec3d(hi) - Vec3d(lo);

    HandleResolution res;
    res.constraints = EdConstraints::none(n);
    res.handleOf.assign(n, -1);
    res.nodesPerHandle.assign(spec.handles.size(), 0);
    for (std::size_t h = 0; h < spec.handles.size(); ++h) {
        const HandleSpec& hs = spec.handles[h];
        const std::string where = msg(spec.source, ": handle ", h, ": ");
        std::vector<std::size_t> sel;
        switch (hs.select) {
        case HandleSpec::Select::Box: {
            const Vec3d a = u.position(hs.boxMin), b = u.position(hs.boxMax);
            for (std::size_t j = 0; j < n; ++j)
                if (g[j].x >= a.x && g[j].x <= b.x && g[j].y >= a.y && g[j].y <= b.y && g[j].z >= a.z && g[j].z <= b.z)
                    sel.push_back(j);
            break;
        }
        case HandleSpec::Select::Sphere: {
            const Vec3d c = u.position(hs.centre);
            const double r = u.length(hs.radius);
            for (std::size_t j = 0; j < n; ++j)
                if (length(g[j] - c) <= r) sel.push_back(j);
            break;
        }
        case HandleSpec::Select::Nodes:
            for (int j : hs.nodes) {
                if (std::size_t(j) >= n)
                    throw InputError(msg(where, "node index ", j, " is out of range (the graph has ", n, " nodes)"));
                sel.push_back(std::size_t(j));
            }
            std::sort(sel.begin(), sel.end());
            sel.erase(std::unique(sel.begin(), sel.end()), sel.end());
            break;
        }
        if (sel.empty()) throw InputError(where + "selects no graph node (enlarge the region or use more nodes)");

        Vec3d pivot(0, 0, 0);
        if (hs.hasPivot) {
            pivot = u.position(hs.pivot);
        } else {
            for (std::size_t j : sel) pivot += g[j];
            pivot = pivot / double(sel.size());
        }
        const Mat3d r = axisAngle(hs.axis, hs.degrees);
        const Vec3d t = u.offset(hs.translate);
        for (std::size_t j : sel) {
            if (res.handleOf[j] >= 0) {
                res.reassignments.push_back({int(j), res.handleOf[j], int(h)});
                --res.nodesPerHandle[std::size_t(res.handleOf[j])];
            }
            res.handleOf[j] = int(h);
            ++res.nodesPerHandle[h];
            res.constraints.fixed[j] = hs.fixed ? 1 : 0;
            res.constraints.hasTarget[j] = hs.fixed ? 0 : 1;
            res.constraints.target[j] = hs.fixed ? g[j] : pivot + r * ((g[j] - pivot) * hs.scale) + t;
        }
    }
    return res;
}

Deformation solveDeformation(const GaussianCloud& rest, const DeformSpec& spec, const EdOptions& options)
{
    const Stopwatch clock;
    DeformationGraph graph = DeformationGraph::build(rest, spec.graph, options.threaded);
    const double graphMs = clock.ms();
    progress(msg("deformation graph: ", graph.nodeCount(), " nodes, k = ", graph.k(), " (", int(graphMs), " ms)"));
    Deformation d = solveDeformation(graph, rest, spec, options);
    d.report.graphMs = graphMs;
    return d;
}

namespace {
/// A solve that overflowed or ran out of iterations must not pass for a deformation (it used to
/// give an undeformed model with null energies and exit 0).
void checkSolve(const Deformation& d, const std::string& source, const EdOptions& options)
{
    const EdReport& r = d.report.solver;
    bool finite = std::isfinite(r.final.total());
    for (std::size_t j = 0; finite && j < d.transforms.size(); ++j) {
        const Vec3d moved = d.graph.nodes()[j] + d.transforms.t[j];
        for (int a = 0; a < 3; ++a) finite = finite && std::fabs(moved[a]) <= 1e15;
        for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b) finite = finite && std::isfinite(d.transforms.A[j][a][b]);
    }
    if (!finite)
        throw InputError(msg(source, ": the deformation solve overflowed (energy ", r.final.total(),
                             "): are the handles' translations, scales or angles far too large for the model?"));
    if (!r.converged)
        throw InputError(msg(source, ": the deformation solve did not converge (", r.iterations, " of at most ",
                             options.maxIterations, " Gauss-Newton iterations, energy ", r.final.total(),
                             "): are the handles' translations, scales or angles far too large for the model?"));
}
} // namespace

Deformation solveDeformation(const DeformationGraph& graph, const GaussianCloud& rest, const DeformSpec& spec,
                             const EdOptions& options, const NodeTransforms* warmStart)
{
    Deformation d;
    d.graph = graph;
    const Stopwatch clock;
    d.handles = resolveHandles(spec, d.graph, rest);
    d.report.resolveMs = clock.ms();
    for (const NodeReassignment& r : d.handles.reassignments)
        progress(msg(spec.source, ": node ", r.node, " selected by handle ", r.fromHandle, " and handle ", r.toHandle,
                     "; handle ", r.toHandle, " wins"));
    const EdConstraints& c = d.handles.constraints;
    d.transforms = solveEd(d.graph, c, options, &d.report.solver, warmStart);
    checkSolve(d, spec.source, options);

    const std::size_t n = d.graph.nodeCount();
    d.nodeMoving.assign(n, 0);
    double sum = 0.0;
    for (std::size_t j = 0; j < n; ++j) {
        if (c.fixed[j]) {
            ++d.report.fixedNodes;
            continue;
        }
        const Mat3d& a = d.transforms.A[j];
        bool identity = d.transforms.t[j].x == 0.0 && d.transforms.t[j].y == 0.0 && d.transforms.t[j].z == 0.0;
        for (int r = 0; r < 3; ++r)
            for (int q = 0; q < 3; ++q) identity = identity && a[r][q] == (r == q ? 1.0 : 0.0);
        d.nodeMoving[j] = identity ? 0 : 1;
        if (c.hasTarget[j]) {
            ++d.report.targetNodes;
            const double e = length(d.graph.nodes()[j] + d.transforms.t[j] - c.target[j]);
            d.report.residualMax = std::max(d.report.residualMax, e);
            sum += e;
        }
    }
    d.report.freeNodes = n - d.report.fixedNodes;
    d.report.residualMean = d.report.targetNodes ? sum / double(d.report.targetNodes) : 0.0;
    d.report.nodesPerHandle = d.handles.nodesPerHandle;
    d.report.reassignments = d.handles.reassignments;
    progress(msg("ED solve: ", d.report.solver.iterations, " iterations, E = ", d.report.solver.final.total(),
                 ", handle residual max ", d.report.residualMax, " (", int(d.report.solver.ms), " ms)"));
    return d;
}

} // namespace splatwarp
