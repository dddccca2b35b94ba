#include "render/RayMarcher.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/Error.h"
#include "core/ParallelFor.h"

namespace splatwarp {

namespace {

/// Ray-box slab intersection; false when the ray misses.
bool clipRay(const Vec3d& o, const Vec3d& d, const Vec3d& lo, const Vec3d& hi, double& t0, double& t1)
{
    t0 = 0.0;
    t1 = 1e300;
    for (int a = 0; a < 3; ++a) {
        if (std::fabs(d[a]) < 1e-300) {
            if (o[a] < lo[a] || o[a] > hi[a]) return false;
            continue;
        }
        double ta = (lo[a] - o[a]) / d[a], tb = (hi[a] - o[a]) / d[a];
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
    }
    return t1 > t0;
}

void marchPixel(const VolumeLookup& lookup, const Camera& cam, const Vec3d& lo, const Vec3d& hi,
                const RayMarchOptions& o, int x, int y, std::vector<float>& buf, float* out)
{
    const Vec3d local((x + 0.5 - cam.cx) / cam.fx, (y + 0.5 - cam.cy) / cam.fy, 1.0);
    Vec3d d = cam.rotation.transposed() * local;
    d = d / length(d);
    const Vec3d origin = cam.centre();
    double t0 = 0, t1 = 0, transmittance = 1.0;
    double rgb[3] = {0, 0, 0};
    if (clipRay(origin, d, lo, hi, t0, t1)) {
        const std::size_t n = std::size_t(std::ceil((t1 - t0) / o.step));
        const double dt = (t1 - t0) / double(n);
        buf.resize(7 * n);
        float* pts = buf.data();
        for (std::size_t k = 0; k < n; ++k) {
            const Vec3d p = origin + d * (t0 + (double(k) + 0.5) * dt);
            for (int a = 0; a < 3; ++a) pts[3 * k + std::size_t(a)] = float(p[a]);
        }
        float* sigma = pts + 3 * n;
        float* colour = sigma + n;
        lookup(pts, n, sigma, colour);
        for (std::size_t k = 0; k < n && transmittance > 1e-4; ++k) {
            const double absorbed = 1.0 - std::exp(-std::max(0.0f, sigma[k]) * dt);
            for (int c = 0; c < 3; ++c) rgb[c] += transmittance * absorbed * colour[3 * k + std::size_t(c)];
            transmittance *= 1.0 - absorbed;
        }
    }
    for (int c = 0; c < 3; ++c) out[c] = float(rgb[c] + transmittance * o.background[c]);
    out[3] = float(1.0 - transmittance);
}

} // namespace

Image rayMarch(const VolumeLookup& lookup, const Vec3d& lo, const Vec3d& hi, const Camera& camera,
               const RayMarchOptions& o)
{
    if (!(o.step > 0)) throw InputError("ray marcher: step must be positive");
    if (camera.width <= 0 || camera.height <= 0 || !(camera.fx > 0) || !(camera.fy > 0))
        throw InputError("ray marcher: camera needs a positive size and focal length");
    Image image(camera.width, camera.height, 4);
    parallelForRange(std::size_t(camera.height), 4, o.threaded, [&](std::size_t begin, std::size_t end) {
        std::vector<float> buf; // ray sample scratch, shared by the rows of one range
        for (int y = int(begin); y != int(end); ++y)
            for (int x = 0; x < camera.width; ++x) marchPixel(lookup, camera, lo, hi, o, x, y, buf, &image.at(x, y, 0));
    });
    return image;
}

} // namespace splatwarp
