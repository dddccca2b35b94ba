#include "mesh/MeshRasterizer.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "core/Error.h"
#include "core/ParallelFor.h"

namespace splatwarp {

namespace {

/// Rows per band: each band owns its z-buffer rows, so bands run in parallel without sharing.
constexpr int kBandRows = 16;

/// A clipped vertex in camera space with its barycentric coordinates in the mesh triangle.
struct ClipVertex {
    Vec3d p, bary;
};

/// A screen triangle: pixel positions, 1/z and the mesh barycentrics divided by z (perspective-correct).
struct ScreenTriangle {
    double x[3], y[3], invZ[3];
    Vec3d baryZ[3];
    std::size_t face;
    int y0, y1; ///< inclusive pixel rows whose centres it may cover
};

ClipVertex lerp(const ClipVertex& a, const ClipVertex& b, double t)
{
    ClipVertex r;
    r.p = a.p + (b.p - a.p) * t;
    r.bary = a.bary + (b.bary - a.bary) * t;
    return r;
}

/// Sutherland-Hodgman against z = near: a triangle becomes 0, 3 or 4 vertices.
int clipNear(const ClipVertex in[3], ClipVertex out[4])
{
    int n = 0;
    for (int i = 0; i < 3; ++i) {
        const ClipVertex &a = in[i], &b = in[(i + 1) % 3];
        const bool ia = a.p.z > kMeshNearPlane, ib = b.p.z > kMeshNearPlane;
        if (ia) out[n++] = a;
        if (ia != ib) out[n++] = lerp(a, b, (kMeshNearPlane - a.p.z) / (b.p.z - a.p.z));
    }
    return n;
}

void addScreenTriangle(const ClipVertex& a, const ClipVertex& b, const ClipVertex& c, std::size_t face,
                       const Camera& cam, std::vector<ScreenTriangle>& out)
{
    ScreenTriangle t;
    const ClipVertex* v[3] = {&a, &b, &c};
    double ylo = 1e300, yhi = -1e300;
    for (int k = 0; k < 3; ++k) {
        const double iz = 1.0 / v[k]->p.z;
        t.x[k] = cam.fx * v[k]->p.x * iz + cam.cx;
        t.y[k] = cam.fy * v[k]->p.y * iz + cam.cy;
        t.invZ[k] = iz;
        t.baryZ[k] = v[k]->bary * iz;
        ylo = std::min(ylo, t.y[k]);
        yhi = std::max(yhi, t.y[k]);
    }
    // Rows whose centre y + 0.5 lies in [ylo, yhi].
    t.y0 = int(std::max(0.0, std::ceil(ylo - 0.5)));
    t.y1 = int(std::min(double(cam.height - 1), std::floor(yhi - 0.5)));
    t.face = face;
    if (t.y0 <= t.y1) out.push_back(t);
}

std::vector<ScreenTriangle> projectTriangles(const TriangleMesh& mesh, const Camera& cam)
{
    std::vector<ScreenTriangle> out;
    out.reserve(mesh.triangleCount());
    for (std::size_t f = 0; f < mesh.triangleCount(); ++f) {
        ClipVertex in[3], clipped[4];
        for (int k = 0; k < 3; ++k) {
            const std::size_t i = mesh.triangles[3 * f + std::size_t(k)];
            in[k].p = cam.rotation * Vec3d(mesh.vertex(i)) + cam.translation;
            in[k].bary[k] = 1.0;
        }
        const int n = clipNear(in, clipped);
        for (int k = 1; k + 1 < n; ++k) addScreenTriangle(clipped[0], clipped[k], clipped[k + 1], f, cam, out);
    }
    return out;
}

/// Rasterise every triangle into rows [r0, r1] of a colour + coverage image (z-buffered).
void rasteriseBand(const TriangleMesh& mesh, const std::vector<ScreenTriangle>& tris, int width, int r0, int r1,
                   std::vector<Vec3d>& colour, std::vector<char>& covered)
{
    std::vector<double> depth(std::size_t(width) * std::size_t(r1 - r0 + 1), std::numeric_limits<double>::infinity());
    for (const ScreenTriangle& t : tris) {
        if (t.y1 < r0 || t.y0 > r1) continue;
        const double area = (t.x[1] - t.x[0]) * (t.y[2] - t.y[0]) - (t.x[2] - t.x[0]) * (t.y[1] - t.y[0]);
        if (!(std::abs(area) > 1e-12)) continue;
        const double xlo = std::min({t.x[0], t.x[1], t.x[2]}), xhi = std::max({t.x[0], t.x[1], t.x[2]});
        const int x0 = int(std::max(0.0, std::ceil(xlo - 0.5))), x1 = int(std::min(double(width - 1), std::floor(xhi - 0.5)));
        for (int y = std::max(r0, t.y0); y <= std::min(r1, t.y1); ++y)
            for (int x = x0; x <= x1; ++x) {
                const double px = x + 0.5, py = y + 0.5;
                double w[3];
                for (int k = 0; k < 3; ++k) {
                    const int a = (k + 1) % 3, b = (k + 2) % 3;
                    w[k] = ((t.x[b] - t.x[a]) * (py - t.y[a]) - (px - t.x[a]) * (t.y[b] - t.y[a])) / area;
                }
                if (w[0] < 0 || w[1] < 0 || w[2] < 0) continue; // shared edges: both sides cover, the z-test picks one
                const double iz = w[0] * t.invZ[0] + w[1] * t.invZ[1] + w[2] * t.invZ[2];
                const std::size_t k = std::size_t(y - r0) * std::size_t(width) + std::size_t(x);
                if (!(1.0 / iz < depth[k])) continue;
                depth[k] = 1.0 / iz;
                const Vec3d bary = (t.baryZ[0] * w[0] + t.baryZ[1] * w[1] + t.baryZ[2] * w[2]) / iz;
                const std::size_t o = std::size_t(y) * std::size_t(width) + std::size_t(x);
                colour[o] = mesh.colourAt(t.face, bary);
                covered[o] = 1;
            }
    }
}

} // namespace

Image renderMesh(const TriangleMesh& mesh, const Camera& camera, const MeshRenderOptions& o)
{
    mesh.checkValid();
    if (camera.width <= 0 || camera.height <= 0 || !(camera.fx > 0) || !(camera.fy > 0))
        throw InputError(msg("camera '", camera.name, "' needs a positive image size and focal length"));
    if (o.samples < 1 || o.samples > 8) throw InputError(msg("mesh samples per pixel axis must be 1..8, got ", o.samples));
    const int s = o.samples;
    const Camera fine = s == 1 ? camera : camera.resized(camera.width * s, camera.height * s);
    const std::vector<ScreenTriangle> tris = projectTriangles(mesh, fine);
    const std::size_t n = std::size_t(fine.width) * std::size_t(fine.height);
    std::vector<Vec3d> colour(n);
    std::vector<char> covered(n, 0);
    const int bands = (fine.height + kBandRows - 1) / kBandRows;
    parallelFor(std::size_t(bands), 1, o.threaded, [&](std::size_t band) {
        const int r0 = int(band) * kBandRows;
        rasteriseBand(mesh, tris, fine.width, r0, std::min(fine.height - 1, r0 + kBandRows - 1), colour, covered);
    });
    Image image(camera.width, camera.height, 4);
    const double inv = 1.0 / double(s * s);
    for (int y = 0; y < camera.height; ++y)
        for (int x = 0; x < camera.width; ++x) {
            Vec3d sum;
            int hits = 0;
            for (int dy = 0; dy < s; ++dy)
                for (int dx = 0; dx < s; ++dx) {
                    const std::size_t k = std::size_t(y * s + dy) * std::size_t(fine.width) + std::size_t(x * s + dx);
                    sum += covered[k] ? colour[k] : Vec3d(o.background);
                    hits += covered[k];
                }
            for (int c = 0; c < 3; ++c) image.at(x, y, c) = float(sum[c] * inv);
            image.at(x, y, 3) = float(hits * inv);
        }
    return image;
}

} // namespace splatwarp
