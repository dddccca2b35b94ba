#include <gtest/gtest.h>

#include <cmath>

#include "core/Error.h"
#include "render/RayMarcher.h"

namespace splatwarp {
namespace {

// A uniform slab inside its box: every ray through it transmits exp(-sigma * path length).
TEST(RayMarcher, UniformSlabTransmittance)
{
    const double sigma = 1.7, thickness = 0.6;
    const VolumeLookup slab = [&](const float*, std::size_t m, float* s, float* rgb) {
        for (std::size_t k = 0; k < m; ++k) {
            s[k] = float(sigma);
            rgb[3 * k] = 1.0f, rgb[3 * k + 1] = 0.5f, rgb[3 * k + 2] = 0.25f;
        }
    };
    const Camera cam = Camera::lookAt(Vec3d(0, 0, 5), Vec3d(0, 0, 0), Vec3d(0, 1, 0), 10.0, 16, 16);
    RayMarchOptions o;
    o.step = 0.01;
    const Image im = rayMarch(slab, Vec3d(-1, -1, -thickness / 2), Vec3d(1, 1, thickness / 2), cam, o);
    for (int y = 0; y < 16; ++y)
        for (int x = 0; x < 16; ++x) {
            const Vec3d local((x + 0.5 - cam.cx) / cam.fx, (y + 0.5 - cam.cy) / cam.fy, 1.0);
            const double path = thickness * length(local) / local.z; // slanted ray through the slab
            const double t = std::exp(-sigma * path);
            EXPECT_NEAR(1.0 - im.at(x, y, 3), t, 1e-4);
            EXPECT_NEAR(im.at(x, y, 0), 1.0 - t, 1e-4); // emission = absorbed fraction times colour
            EXPECT_NEAR(im.at(x, y, 2), 0.25 * (1.0 - t), 1e-4);
        }
}

TEST(RayMarcher, MissingTheBoxIsBackground)
{
    const VolumeLookup any = [](const float*, std::size_t m, float* s, float* rgb) {
        for (std::size_t k = 0; k < m; ++k) s[k] = 5.0f, rgb[3 * k] = rgb[3 * k + 1] = rgb[3 * k + 2] = 1.0f;
    };
    const Camera cam = Camera::lookAt(Vec3d(0, 0, 5), Vec3d(0, 0, 0), Vec3d(0, 1, 0), 10.0, 8, 8);
    RayMarchOptions o;
    o.step = 0.01;
    o.background = Vec3f{0.1f, 0.2f, 0.3f};
    const Image im = rayMarch(any, Vec3d(10, 10, 10), Vec3d(11, 11, 11), cam, o);
    EXPECT_FLOAT_EQ(im.at(3, 3, 3), 0.0f);
    EXPECT_FLOAT_EQ(im.at(3, 3, 2), 0.3f);
    o.step = 0;
    EXPECT_THROW(rayMarch(any, Vec3d(0, 0, 0), Vec3d(1, 1, 1), cam, o), InputError);
}

} // namespace
} // namespace splatwarp
