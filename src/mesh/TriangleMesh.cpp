#include "mesh/TriangleMesh.h"

#include <algorithm>
#include <cmath>

#include "core/Error.h"

namespace splatwarp {

void TriangleMesh::checkValid() const
{
    const std::size_t v = vertexCount(), f = triangleCount();
    if (positions.size() % 3 != 0 || triangles.size() % 3 != 0) throw InputError(msg(name, ": inconsistent mesh arrays"));
    if (v == 0) throw InputError(msg(name, ": the mesh has no vertices"));
    if (f == 0) throw InputError(msg(name, ": the mesh has no triangles"));
    // Splats of a mesh beyond 1e14, or under 1e-12 across, have centres or log-scales that every
    // model reader refuses (|centre| > 1e15, |log-scale| > 40): refused here, before a training
    // that could only end so.
    double extent = 0;
    for (std::size_t i = 0; i < positions.size(); ++i) {
        if (!std::isfinite(positions[i])) throw InputError(msg(name, ": vertex ", i / 3, " is not finite"));
        if (std::fabs(positions[i]) > 1e14)
            throw InputError(msg(name, ": vertex ", i / 3, " lies ", std::fabs(positions[i]), " from the origin, beyond 1e14 (scale or move the mesh)"));
        extent = std::max(extent, std::fabs(double(positions[i]) - positions[i % 3]));
    }
    if (extent < 1e-12) throw InputError(msg(name, ": the mesh is ", extent, " across, below 1e-12 (scale it up)"));
    for (std::uint32_t k : triangles)
        if (k >= v) throw InputError(msg(name, ": triangle index ", k, " is out of range (", v, " vertices)"));
    if ((!uvs.empty() && uvs.size() != 2 * v) || (!colours.empty() && colours.size() != 3 * v))
        throw InputError(msg(name, ": UV or colour arrays do not match the vertex count"));
    for (float x : uvs)
        if (!std::isfinite(x)) throw InputError(msg(name, ": a texture coordinate is not finite"));
    // A NaN colour trained to a NaN loss and was scored "PSNR inf" (a perfect match).
    for (std::size_t i = 0; i < colours.size(); ++i)
        if (!std::isfinite(colours[i])) throw InputError(msg(name, ": the colour of vertex ", i / 3, " is not finite"));
    for (const MeshMaterial& m : materials)
        if (!std::isfinite(m.colour.x) || !std::isfinite(m.colour.y) || !std::isfinite(m.colour.z))
            throw InputError(msg(name, ": a material's colour is not finite"));
    if (materialOf.size() != f) throw InputError(msg(name, ": ", materialOf.size(), " material indices for ", f, " triangles"));
    for (std::uint32_t m : materialOf)
        if (m >= materials.size()) throw InputError(msg(name, ": material index ", m, " is out of range"));
    for (const MeshMaterial& m : materials) {
        if (m.texture >= int(textures.size())) throw InputError(msg(name, ": texture index ", m.texture, " is out of range"));
        if (m.texture >= 0 && uvs.empty()) throw InputError(msg(name, ": a textured material but no texture coordinates"));
    }
    for (const Image& t : textures)
        if (t.empty() || t.channels < 3) throw InputError(msg(name, ": an empty texture"));
}

void TriangleMesh::bounds(Vec3d& lo, Vec3d& hi) const
{
    lo = Vec3d(1e300, 1e300, 1e300);
    hi = -lo;
    for (std::size_t i = 0; i < vertexCount(); ++i)
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], double(positions[3 * i + std::size_t(a)]));
            hi[a] = std::max(hi[a], double(positions[3 * i + std::size_t(a)]));
        }
}

namespace {

/// Bilinear texel lookup with wrap-around; v = 0 is the bottom row (OBJ/assimp convention).
Vec3d sampleTexture(const Image& t, double u, double v)
{
    const double x = u * t.width - 0.5, y = (1.0 - v) * t.height - 0.5;
    const double fx = std::floor(x), fy = std::floor(y);
    const double ax = x - fx, ay = y - fy;
    const auto wrap = [](long long i, int n) { return int(((i % n) + n) % n); };
    Vec3d r;
    for (int dy = 0; dy < 2; ++dy)
        for (int dx = 0; dx < 2; ++dx) {
            const int xi = wrap((long long)fx + dx, t.width), yi = wrap((long long)fy + dy, t.height);
            const double w = (dx ? ax : 1.0 - ax) * (dy ? ay : 1.0 - ay);
            for (int c = 0; c < 3; ++c) r[c] += w * t.at(xi, yi, c);
        }
    return r;
}

} // namespace

Vec3d TriangleMesh::colourAt(std::size_t f, const Vec3d& b) const
{
    const MeshMaterial& m = materials[materialOf[f]];
    const std::uint32_t* v = &triangles[3 * f];
    Vec3d colour(1, 1, 1);
    if (!colours.empty()) {
        colour = Vec3d();
        for (int k = 0; k < 3; ++k)
            colour += Vec3d(colours[3 * v[k]], colours[3 * v[k] + 1], colours[3 * v[k] + 2]) * b[k];
    }
    if (m.texture < 0) return colours.empty() ? Vec3d(m.colour) : colour;
    double u = 0, w = 0;
    for (int k = 0; k < 3; ++k) {
        u += uvs[2 * v[k]] * b[k];
        w += uvs[2 * v[k] + 1] * b[k];
    }
    const Vec3d tex = sampleTexture(textures[std::size_t(m.texture)], u, w);
    return Vec3d(tex.x * colour.x, tex.y * colour.y, tex.z * colour.z);
}

void applyProceduralColour(TriangleMesh& mesh, double periods)
{
    Vec3d lo, hi;
    mesh.bounds(lo, hi);
    const double extent = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z, 1e-30});
    const double k = 2.0 * 3.14159265358979323846 * periods / extent;
    mesh.colours.resize(mesh.positions.size());
    for (std::size_t i = 0; i < mesh.vertexCount(); ++i) {
        const Vec3d p = Vec3d(mesh.vertex(i)) - lo;
        // Each channel follows a different direction, so no two regions look alike.
        const double s[3] = {std::sin(k * (p.x + 0.5 * p.y)), std::sin(k * (p.y + 0.5 * p.z) + 1.0),
                             std::sin(k * (p.z + 0.5 * p.x) + 2.0)};
        for (int c = 0; c < 3; ++c) mesh.colours[3 * i + std::size_t(c)] = float(0.5 + 0.35 * s[c]);
    }
    for (MeshMaterial& m : mesh.materials) m.texture = -1;
    mesh.textures.clear();
}

} // namespace splatwarp
