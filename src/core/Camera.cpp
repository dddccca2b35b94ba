#include "core/Camera.h"

#include <cmath>

namespace splatwarp {

namespace {

Vec3d normalised(const Vec3d& v)
{
    const double n = length(v);
    return n > 0 ? v / n : v;
}

} // namespace

Vec3d Camera::centre() const { return -(rotation.transposed() * translation); }

Camera Camera::resized(int newWidth, int newHeight) const
{
    Camera c = *this;
    const double sx = double(newWidth) / width, sy = double(newHeight) / height;
    c.fx *= sx;
    c.cx *= sx;
    c.fy *= sy;
    c.cy *= sy;
    c.width = newWidth;
    c.height = newHeight;
    return c;
}

Camera Camera::lookAt(const Vec3d& eye, const Vec3d& target, const Vec3d& up, double fovYDeg, int width, int height)
{
    const Vec3d forward = normalised(target - eye);
    Vec3d right = cross(forward, up);
    if (length(right) < 1e-9 * length(up)) {
        // Looking along the up axis: any perpendicular "up" gives a valid (if arbitrary) roll.
        const Vec3d alt = std::abs(forward.x) < 0.9 ? Vec3d(1, 0, 0) : Vec3d(0, 1, 0);
        right = cross(forward, alt);
    }
    right = normalised(right);
    const Vec3d down = cross(forward, right);
    Camera c;
    for (int k = 0; k < 3; ++k) {
        c.rotation.m[0][k] = right[k];
        c.rotation.m[1][k] = down[k];
        c.rotation.m[2][k] = forward[k];
    }
    c.translation = -(c.rotation * eye);
    c.width = width;
    c.height = height;
    c.fy = 0.5 * height / std::tan(0.5 * radians(fovYDeg));
    c.fx = c.fy;
    c.cx = 0.5 * width;
    c.cy = 0.5 * height;
    return c;
}

Camera Camera::fromCameraToWorld(const Mat3d& c2w, const Vec3d& centre)
{
    Camera cam;
    cam.rotation = c2w.transposed();
    cam.translation = -(cam.rotation * centre);
    return cam;
}

} // namespace splatwarp
