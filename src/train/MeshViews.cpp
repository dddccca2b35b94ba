#include "train/MeshViews.h"

#include <algorithm>
#include <cmath>
#include <random>

#include "core/Error.h"
#include "sh/SphericalHarmonics.h"

namespace splatwarp {

void meshSphere(const TriangleMesh& mesh, Vec3d& centre, double& radius)
{
    Vec3d lo, hi;
    mesh.bounds(lo, hi);
    centre = (lo + hi) * 0.5;
    radius = 0;
    for (std::size_t i = 0; i < mesh.vertexCount(); ++i) radius = std::max(radius, length(Vec3d(mesh.vertex(i)) - centre));
    if (!(radius > 0)) radius = 1.0;
}

std::vector<Camera> meshCameras(const TriangleMesh& mesh, const SphereViewOptions& options)
{
    Vec3d centre;
    double radius = 0;
    meshSphere(mesh, centre, radius);
    return sphereCameras(centre, radius, options);
}

std::vector<TrainingView> renderMeshViews(const TriangleMesh& mesh, const std::vector<Camera>& cameras,
                                          const MeshRenderOptions& options)
{
    std::vector<TrainingView> views;
    for (const Camera& c : cameras) {
        TrainingView v;
        v.camera = c;
        v.image = renderMesh(mesh, c, options);
        views.push_back(std::move(v));
    }
    return views;
}

GaussianCloud meshSurfaceGaussians(const TriangleMesh& mesh, std::size_t count, unsigned seed)
{
    mesh.checkValid();
    const std::size_t f = mesh.triangleCount();
    std::vector<double> cumulative(f);
    double total = 0;
    for (std::size_t t = 0; t < f; ++t) {
        const Vec3d a(mesh.vertex(mesh.triangles[3 * t])), b(mesh.vertex(mesh.triangles[3 * t + 1])),
            c(mesh.vertex(mesh.triangles[3 * t + 2]));
        total += 0.5 * length(cross(b - a, c - a));
        cumulative[t] = total;
    }
    if (!(total > 0)) throw InputError(msg(mesh.name, ": the mesh has no area to place Gaussians on"));
    const double spacing = std::sqrt(total / double(std::max<std::size_t>(count, 1)));
    GaussianCloud g;
    g.resize(count, 0);
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (std::size_t i = 0; i < count; ++i) {
        const std::size_t t = std::size_t(std::lower_bound(cumulative.begin(), cumulative.end(), u(rng) * total) - cumulative.begin());
        const std::size_t tri = std::min(t, f - 1);
        double r1 = std::sqrt(u(rng)), r2 = u(rng);
        const Vec3d bary(1 - r1, r1 * (1 - r2), r1 * r2); // uniform on the triangle
        const Vec3d a(mesh.vertex(mesh.triangles[3 * tri])), b(mesh.vertex(mesh.triangles[3 * tri + 1])),
            c(mesh.vertex(mesh.triangles[3 * tri + 2]));
        g.setMean(i, Vec3f(a * bary.x + b * bary.y + c * bary.z));
        // A disc in the triangle's plane: the rotation takes z to the normal.
        const Vec3d n = cross(b - a, c - a), e0 = b - a;
        const double nl = length(n), el = length(e0);
        if (nl > 0 && el > 0) {
            const Vec3d z = n / nl, x = e0 / el, y = cross(z, x);
            Mat3d r;
            for (int k = 0; k < 3; ++k) {
                r.m[k][0] = x[k];
                r.m[k][1] = y[k];
                r.m[k][2] = z[k];
            }
            const Quat<double> q = matrixToQuat(r);
            g.setRotation(i, Quatf{float(q.w), float(q.x), float(q.y), float(q.z)});
        }
        const float s = float(std::log(spacing));
        g.logScales[3 * i] = g.logScales[3 * i + 1] = s;
        g.logScales[3 * i + 2] = s - std::log(10.0f); // flat, not degenerate: it may still grow
        g.opacities[i] = std::log(0.1f / 0.9f);
        const Vec3d colour = mesh.colourAt(tri, bary);
        for (int ch = 0; ch < 3; ++ch) g.sh[std::size_t(ch) + 3 * i] = float((colour[ch] - 0.5) / kShC0);
    }
    return g;
}

} // namespace splatwarp
