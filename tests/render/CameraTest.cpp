#include <gtest/gtest.h>

#include <cmath>

#include "core/Error.h"
#include "render/Camera.h"
#include "render/RenderTestUtil.h"
#include "demo/DemoModels.h"
#include "io/GaussianIO.h"
#include "support/TestSupport.h"

namespace splatwarp {
namespace {

using test::project;

TEST(CameraTest, OrbitCamerasFrameTheModel)
{
    const GaussianCloud g = test::smallSample("stripes", 2000); // 4 x 1 x 1 bar along x
    OrbitOptions o;
    o.views = 4;
    o.width = 64;
    o.height = 48;
    const auto cams = orbitCameras(g, o);
    ASSERT_EQ(cams.size(), 4u);
    Vec3f lo, hi;
    centreBounds(g, lo, hi);
    const Vec3d mid = (Vec3d(lo) + Vec3d(hi)) * 0.5;
    for (const Camera& c : cams) {
        // Rotation orthonormal with det +1; the box centre projects near the image centre.
        const Mat3d rrt = c.rotation * c.rotation.transposed();
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) EXPECT_NEAR(rrt.m[i][j], i == j ? 1.0 : 0.0, 1e-12);
        EXPECT_NEAR(c.rotation.determinant(), 1.0, 1e-12);
        const Vec3d p = project(c, mid);
        EXPECT_NEAR(p.x, 32, 1.0);
        EXPECT_NEAR(p.y, 24, 1.0);
        // Every bar end is inside the view.
        for (double x : {-2.0, 2.0}) {
            const Vec3d e = project(c, Vec3d(x, 0, 0));
            EXPECT_GT(e.x, 0);
            EXPECT_LT(e.x, 64);
        }
    }
    // Up is the smallest extent (y or z); the first camera sees the bar broadside: its ends are
    // far apart on screen.
    const Vec3d a = project(cams[0], Vec3d(-2, 0, 0)), b = project(cams[0], Vec3d(2, 0, 0));
    EXPECT_GT(std::abs(a.x - b.x), 32);
    // Explicit up axis: world +z projects upwards in the image.
    o.up = "z";
    const Camera cz = orbitCameras(g, o)[1];
    EXPECT_LT(project(cz, mid + Vec3d(0, 0, 0.5)).y, project(cz, mid).y);
    EXPECT_THROW(parseUpAxis("w"), InputError);
    EXPECT_NEAR(parseUpAxis("-y").y, -1.0, 0);
}

/// Centres of a y-down capture: a wide ground slab at y in [0.9, 1] under a thin post up to y = -1.
GaussianCloud groundAndPost()
{
    GaussianCloud g;
    g.resize(1200, 0);
    for (std::size_t i = 0; i < g.size(); ++i) {
        const float t = float(i % 40) / 39.0f, u = float(i / 40) / 29.0f;
        if (i < 1000)
            g.setMean(i, Vec3f(-2.0f + 4.0f * t, 0.9f + 0.1f * u, -2.0f + 4.0f * u));
        else
            g.setMean(i, Vec3f(0.05f * t, 1.0f - 2.0f * float(i - 1000) / 199.0f, 0.05f * u));
    }
    return g;
}

// --up auto: a capture standing on a ground patch at +y (y down, as graphdeco/PlayCanvas files)
// renders upright: -y is up, so the post's top (y = -1) lands above the ground in the image.
TEST(CameraTest, AutoUpStandsYDownCapturesUpright)
{
    const GaussianCloud g = groundAndPost();
    OrbitOptions o;
    o.views = 3;
    o.boundsQuantile = 0.0;
    for (const Camera& c : orbitCameras(g, o))
        EXPECT_LT(project(c, Vec3d(0, -1, 0)).y, project(c, Vec3d(0, 1, 0)).y) << c.name;
    // A symmetric bar keeps +axis (the old choice).
    const GaussianCloud bar = test::smallSample("stripes", 2000);
    const Camera b = orbitCameras(bar, o)[0];
    const Vec3d up = Vec3d(b.rotation.m[1][0], b.rotation.m[1][1], b.rotation.m[1][2]) * -1.0; // -(image down)
    EXPECT_GT(up.y + up.z, 0.3);
}

TEST(CameraTest, AutoUpOnPlaybotIsMinusY)
{
    SPLATWARP_REQUIRE_DATA(path, "splats/playbot-31k-sh2.ply");
    const GaussianCloud g = readGaussians(path);
    const Camera c = orbitCameras(g)[0];
    // Image "down" (camera row 1) points along +y in world: world up is -y.
    EXPECT_GT(c.rotation.m[1][1], 0.5);
}

TEST(CameraTest, ResizedScalesIntrinsics)
{
    Camera c = Camera::lookAt(Vec3d(0, 0, -3), Vec3d(0, 0, 0), Vec3d(0, -1, 0), 60, 100, 50);
    const Camera r = c.resized(50, 25);
    EXPECT_DOUBLE_EQ(r.fx, c.fx / 2);
    EXPECT_DOUBLE_EQ(r.cy, c.cy / 2);
    EXPECT_NEAR(c.fy, 25.0 / std::tan(M_PI / 6), 1e-9);
}

} // namespace
} // namespace splatwarp
