#pragma once
// Naive double-precision reference of the embedded-deformation energies that EdSolver minimises
// (E_rot, E_reg, E_con of Sumner et al.), written from the definitions, independent of the solver's
// code. Like the solver it works in normalised coordinates: x_n = (x - centre) / scale with the
// centre and the largest edge of the nodes' bounding box; fixed nodes count as A = I, t = 0.
#include <algorithm>
#include <cstddef>

#include "core/SmallMath.h"
#include "deform/DeformationGraph.h"
#include "deform/EdSolver.h"
#include "deform/NodeTransforms.h"

namespace splatwarp::test {

inline EdEnergies referenceEdEnergies(const DeformationGraph& graph, const EdConstraints& c, const EdOptions& o,
                                      const NodeTransforms& x)
{
    const std::size_t n = graph.nodeCount();
    Vec3d lo = graph.nodes()[0], hi = lo;
    for (const Vec3d& p : graph.nodes())
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], p[a]);
            hi[a] = std::max(hi[a], p[a]);
        }
    const Vec3d centre = (lo + hi) * 0.5;
    double scale = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
    if (!(scale > 0.0)) scale = 1.0;
    auto g = [&](std::size_t j) { return (graph.nodes()[j] - centre) * (1.0 / scale); };
    auto A = [&](std::size_t j) { return c.fixed[j] ? Mat3d::identity() : x.A[j]; };
    auto t = [&](std::size_t j) { return c.fixed[j] ? Vec3d(0, 0, 0) : x.t[j] * (1.0 / scale); };
    EdEnergies e;
    for (std::size_t j = 0; j < n; ++j) {
        if (!c.fixed[j]) {
            const Mat3d a = A(j);
            for (int p = 0; p < 3; ++p)
                for (int q = p; q < 3; ++q) {
                    double d = 0;
                    for (int r = 0; r < 3; ++r) d += a.m[r][p] * a.m[r][q];
                    if (p == q) d -= 1.0;
                    e.rot += d * d;
                }
        }
        for (std::int32_t k : graph.neighbours(j)) {
            const std::size_t kk = std::size_t(k);
            const Vec3d r = A(j) * (g(kk) - g(j)) + g(j) + t(j) - g(kk) - t(kk);
            e.reg += dot(r, r);
        }
        if (c.hasTarget[j] && !c.fixed[j]) {
            const Vec3d r = g(j) + t(j) - (c.target[j] - centre) * (1.0 / scale);
            e.con += dot(r, r);
        }
    }
    e.rot *= o.rotWeight;
    e.reg *= o.regWeight;
    e.con *= o.conWeight;
    return e;
}

} // namespace splatwarp::test
