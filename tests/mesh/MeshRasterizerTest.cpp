#include <gtest/gtest.h>

#include <cmath>

#include "core/Error.h"
#include "mesh/MeshRasterizer.h"

namespace splatwarp {
namespace {

/// A camera at the origin looking down +z (identity pose).
Camera axisCamera(int size, double focal)
{
    Camera c;
    c.width = c.height = size;
    c.fx = c.fy = focal;
    c.cx = c.cy = 0.5 * size;
    return c;
}

/// A 16x16 texture whose texel (i, j) is ((i + 0.5) / 16, (j + 0.5) / 16, 0.25): bilinear lookups
/// of it are exact (R = u, G = 1 - v away from the wrapped border).
Image gradientTexture()
{
    Image t(16, 16, 3);
    for (int j = 0; j < 16; ++j)
        for (int i = 0; i < 16; ++i) {
            t.at(i, j, 0) = (i + 0.5f) / 16.0f;
            t.at(i, j, 1) = (j + 0.5f) / 16.0f;
            t.at(i, j, 2) = 0.25f;
        }
    return t;
}

/// The quad x, y in [-1, 1] on the slanted plane z = 2 + 0.5 x, uv = ((x + 1) / 2, (1 - y) / 2).
TriangleMesh slantedQuad()
{
    TriangleMesh m;
    m.name = "quad";
    for (double y : {-1.0, 1.0})
        for (double x : {-1.0, 1.0}) {
            m.positions.insert(m.positions.end(), {float(x), float(y), float(2.0 + 0.5 * x)});
            m.uvs.insert(m.uvs.end(), {float((x + 1) / 2), float((1 - y) / 2)});
        }
    m.triangles = {0, 1, 3, 0, 3, 2};
    m.materialOf = {0, 0};
    MeshMaterial mat;
    mat.texture = 0;
    m.materials = {mat};
    m.textures = {gradientTexture()};
    return m;
}

// The analytic image: the ray through a pixel centre meets the plane at t = 2 / (1 - 0.5 dx), and
// the texture there is (u, 1 - v, 0.25). Screen-space (affine) interpolation would miss by ~0.03.
TEST(MeshRasterizerTest, TexturedQuadMatchesTheAnalyticImage)
{
    const Camera cam = axisCamera(64, 40.0);
    MeshRenderOptions o;
    o.background = Vec3f(0.1f, 0.2f, 0.3f);
    const Image img = renderMesh(slantedQuad(), cam, o);
    double worst = 0;
    int checked = 0;
    for (int py = 0; py < 64; ++py)
        for (int px = 0; px < 64; ++px) {
            const double dx = (px + 0.5 - 32) / 40.0, dy = (py + 0.5 - 32) / 40.0;
            const double t = 2.0 / (1.0 - 0.5 * dx), x = t * dx, y = t * dy;
            const double u = (x + 1) / 2, v = (1 - y) / 2;
            const bool inside = std::abs(x) < 0.98 && std::abs(y) < 0.98, outside = std::abs(x) > 1.02 || std::abs(y) > 1.02;
            if (outside) {
                EXPECT_FLOAT_EQ(img.at(px, py, 3), 0.0f);
                EXPECT_FLOAT_EQ(img.at(px, py, 2), 0.3f);
            }
            if (!inside) continue;
            EXPECT_FLOAT_EQ(img.at(px, py, 3), 1.0f);
            if (u < 0.04 || u > 0.96 || v < 0.04 || v > 0.96) continue; // the texture wraps there
            worst = std::max({worst, std::abs(img.at(px, py, 0) - u), std::abs(img.at(px, py, 1) - (1 - v)),
                              std::abs(img.at(px, py, 2) - 0.25)});
            ++checked;
        }
    EXPECT_GT(checked, 1000);
    EXPECT_LT(worst, 2e-6); // float texels and output
}

TEST(MeshRasterizerTest, DepthTestSamplesAndThreadsAgree)
{
    TriangleMesh m = slantedQuad();
    // A red square in front of the quad's centre, listed last: the z-buffer, not the order, decides.
    m.textures.clear();
    m.materials = {MeshMaterial{Vec3f(0, 1, 0), -1}, MeshMaterial{Vec3f(1, 0, 0), -1}};
    const std::uint32_t base = std::uint32_t(m.vertexCount());
    for (double y : {-0.3, 0.3})
        for (double x : {-0.3, 0.3}) {
            m.positions.insert(m.positions.end(), {float(x), float(y), 1.5f});
            m.uvs.insert(m.uvs.end(), {0.0f, 0.0f});
        }
    m.triangles.insert(m.triangles.end(), {base, base + 1, base + 3, base, base + 3, base + 2});
    m.materialOf.insert(m.materialOf.end(), {1, 1});
    const Camera cam = axisCamera(48, 31.0); // no edge on a pixel boundary
    const Image img = renderMesh(m, cam);
    EXPECT_FLOAT_EQ(img.at(24, 24, 0), 1.0f);
    EXPECT_FLOAT_EQ(img.at(24, 24, 1), 0.0f);
    EXPECT_FLOAT_EQ(img.at(32, 24, 1), 1.0f); // the quad beside it
    MeshRenderOptions serial;
    serial.threaded = false;
    EXPECT_TRUE(renderMesh(m, cam, serial).pixels == img.pixels);
    // 4x4 samples: the alpha of an edge pixel is its covered fraction, the inside stays exact.
    MeshRenderOptions fine;
    fine.samples = 4;
    const Image aa = renderMesh(m, cam, fine);
    EXPECT_FLOAT_EQ(aa.at(24, 24, 0), 1.0f);
    double partial = 0;
    for (int x = 0; x < 48; ++x)
        if (aa.at(x, 24, 3) > 0 && aa.at(x, 24, 3) < 1) ++partial;
    EXPECT_GE(partial, 1);
}

TEST(MeshRasterizerTest, NearPlaneClipsAndBadInputsThrow)
{
    // A floor triangle reaching behind the camera: only its visible part is drawn, no wrap-around.
    TriangleMesh m;
    m.name = "floor";
    m.positions = {-5, 1, -3, 5, 1, -3, 0, 1, 10};
    m.triangles = {0, 1, 2};
    m.materialOf = {0};
    m.materials = {MeshMaterial()};
    const Image img = renderMesh(m, axisCamera(32, 20.0));
    for (int x = 0; x < 32; ++x) EXPECT_FLOAT_EQ(img.at(x, 0, 3), 0.0f); // above the horizon: nothing
    EXPECT_FLOAT_EQ(img.at(16, 31, 3), 1.0f);                           // down the floor: covered
    m.positions[4] = std::nanf("");
    EXPECT_THROW(renderMesh(m, axisCamera(8, 8.0)), InputError);
    m.positions[4] = 1;
    m.triangles = {0, 1, 7};
    EXPECT_THROW(renderMesh(m, axisCamera(8, 8.0)), InputError);
}

} // namespace
} // namespace splatwarp
