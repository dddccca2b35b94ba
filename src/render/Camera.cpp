#include "render/Camera.h"

#include <algorithm>
#include <cmath>

#include "core/Error.h"

namespace splatwarp {

namespace {

constexpr double kPi = 3.14159265358979323846;

/// Sign of the automatic up axis: captures sit on a ground patch or a base, so their centres crowd
/// at the bottom (playbot, y-down: mean 0.38 of the extent below the box middle); a clear skew
/// (over kAutoUpSkew) points up away from it, anything else keeps +axis (the donut's icing: 0.12).
constexpr double kAutoUpSkew = 0.25;

double autoUpSign(const GaussianCloud& g, int axis, double lo, double hi)
{
    if (!(hi > lo)) return 1.0;
    double sum = 0;
    std::size_t n = 0;
    for (std::size_t i = 0; i < g.size(); ++i) {
        const double v = g.means[3 * i + std::size_t(axis)];
        if (v < lo || v > hi) continue; // the robust box, as the extent
        sum += v;
        ++n;
    }
    const double skew = n > 0 ? (sum / double(n) - 0.5 * (lo + hi)) / (hi - lo) : 0.0;
    return skew > kAutoUpSkew ? -1.0 : 1.0;
}

} // namespace

PinholeView pinholeView(const Camera& camera)
{
    PinholeView v;
    v.rotation = Mat3f::from(camera.rotation);
    v.translation = Vec3f(camera.translation);
    v.centre = Vec3f(camera.centre());
    v.fx = float(camera.fx);
    v.fy = float(camera.fy);
    v.cx = float(camera.cx);
    v.cy = float(camera.cy);
    v.width = camera.width;
    v.height = camera.height;
    return v;
}

Vec3d parseUpAxis(const std::string& name)
{
    const bool negative = !name.empty() && name[0] == '-';
    const std::string axis = name.substr(negative || (!name.empty() && name[0] == '+') ? 1 : 0);
    Vec3d v;
    if (axis == "x")
        v = Vec3d(1, 0, 0);
    else if (axis == "y")
        v = Vec3d(0, 1, 0);
    else if (axis == "z")
        v = Vec3d(0, 0, 1);
    else
        throw InputError(msg("unknown up axis '", name, "' (use x, y, z, -x, -y, -z or auto)"));
    return negative ? -v : v;
}

std::vector<Camera> sphereCameras(const Vec3d& centre, double radius, const SphereViewOptions& o)
{
    if (o.views < 1 || o.views > kMaxViews) throw InputError(msg("sphere views need 1 to ", kMaxViews, " views, got ", o.views));
    if (!(o.fovDeg > 0 && o.fovDeg < 180)) throw InputError(msg("field of view must be in (0, 180) degrees, got ", o.fovDeg));
    if (!(radius > 0) || !(o.distanceFactor > 0)) throw InputError("sphere views need a positive radius and distance");
    if (o.width <= 0 || o.height <= 0) throw InputError(msg("image size must be positive, got ", o.width, "x", o.height));
    const double halfFovY = 0.5 * radians(o.fovDeg);
    const double halfFovX = std::atan(std::tan(halfFovY) * double(o.width) / o.height);
    const double distance = o.distanceFactor * radius / std::sin(std::min(halfFovX, halfFovY));
    const double golden = kPi * (3.0 - std::sqrt(5.0)); // the Fibonacci lattice's azimuth step
    std::vector<Camera> cams;
    for (int k = 0; k < o.views; ++k) {
        const double z = 1.0 - 2.0 * (k + 0.5) / o.views, r = std::sqrt(std::max(0.0, 1.0 - z * z));
        const double azimuth = golden * k + 2.0 * kPi * o.phase;
        const Vec3d dir(r * std::cos(azimuth), z, r * std::sin(azimuth)); // y: the lattice axis
        Camera c = Camera::lookAt(centre + dir * distance, centre, o.up, o.fovDeg, o.width, o.height);
        c.name = msg("view_", k);
        cams.push_back(c);
    }
    return cams;
}

std::vector<Camera> orbitCameras(const GaussianCloud& cloud, const OrbitOptions& o)
{
    if (cloud.empty()) throw InputError("cannot place orbit cameras around an empty model");
    if (o.views < 1 || o.views > kMaxViews) throw InputError(msg("an orbit needs 1 to ", kMaxViews, " views, got ", o.views));
    if (!(o.elevationDeg > -90 && o.elevationDeg < 90))
        throw InputError(msg("orbit elevation must be in (-90, 90) degrees, got ", o.elevationDeg));
    if (!(o.fovDeg > 0 && o.fovDeg < 180)) throw InputError(msg("field of view must be in (0, 180) degrees, got ", o.fovDeg));
    if (!(o.distanceFactor > 0)) throw InputError(msg("distance factor must be positive, got ", o.distanceFactor));
    if (o.width <= 0 || o.height <= 0) throw InputError(msg("image size must be positive, got ", o.width, "x", o.height));
    Vec3d lo, hi;
    for (int a = 0; a < 3; ++a) {
        lo[a] = centreQuantile(cloud, a, o.boundsQuantile);
        hi[a] = centreQuantile(cloud, a, 1.0 - o.boundsQuantile);
    }
    const Vec3d centre = (lo + hi) * 0.5, extent = hi - lo;
    int upAxis = 0;
    Vec3d up;
    if (o.up == "auto") {
        for (int a = 1; a < 3; ++a)
            if (extent[a] < extent[upAxis]) upAxis = a;
        up[upAxis] = autoUpSign(cloud, upAxis, lo[upAxis], hi[upAxis]);
    } else {
        up = parseUpAxis(o.up);
        upAxis = up.x != 0 ? 0 : (up.y != 0 ? 1 : 2);
    }
    // The first camera looks across the longest horizontal axis (a bar is seen broadside).
    const int h0 = (upAxis + 1) % 3, h1 = (upAxis + 2) % 3;
    const int side = extent[h0] <= extent[h1] ? h0 : h1;
    Vec3d a;
    a[side] = 1;
    const Vec3d b = cross(up, a);
    double radius = 0.5 * length(extent);
    if (!(radius > 0)) radius = 1.0; // a single point: any scale will do
    const double halfFovY = 0.5 * radians(o.fovDeg);
    const double halfFovX = std::atan(std::tan(halfFovY) * double(o.width) / o.height);
    const double distance = o.distanceFactor * radius / std::sin(std::min(halfFovX, halfFovY));
    const double elevation = radians(o.elevationDeg);
    std::vector<Camera> cams;
    for (int k = 0; k < o.views; ++k) {
        const double azimuth = 2.0 * kPi * k / o.views;
        const Vec3d dir = (a * std::cos(azimuth) + b * std::sin(azimuth)) * std::cos(elevation) + up * std::sin(elevation);
        Camera c = Camera::lookAt(centre + dir * distance, centre, up, o.fovDeg, o.width, o.height);
        c.name = msg("view_", k);
        cams.push_back(c);
    }
    return cams;
}

} // namespace splatwarp
