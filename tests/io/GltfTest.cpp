/// `.glb` (KHR_gaussian_splatting) reader and writer: splat-transform's file of the 200-Gaussian
/// model decodes to the source PLY, our writer's file decodes to the same values, and broken files
/// are InputErrors naming the file. Tolerances are float32 rounding of the stored quantities.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include <nlohmann/json.hpp>

#include "PlyTestFiles.h"
#include "core/Error.h"
#include "io/GaussianIO.h"
#include "sh/SphericalHarmonics.h"
#include "support/TestSupport.h"

using namespace splatwarp;
using namespace splatwarp::test;

namespace {

std::string fixture(const std::string& name) { return std::string(SPLATWARP_SOURCE_DIR) + "/tests/io/data/" + name; }

double sigmoidD(double x) { return 1 / (1 + std::exp(-x)); }

// Opacity is stored as float(sigmoid(logit)): alpha is off by half a float step at most, and the
// logit by that over d alpha / d logit = a (1 - a), plus the float rounding of the logit read back.
double logitTolerance(float logit)
{
    const double a = sigmoidD(logit);
    const double step = double(std::nextafter(float(a), 2.0f)) - double(float(a));
    return step / (a * (1 - a)) + std::fabs(logit) * std::ldexp(1.0, -23) + 1e-12;
}

// Values after a float32 glb: centres and SH exact, unit quaternions and log(float(exp s)) to a
// few float steps, opacity by logitTolerance(). q and -q are one rotation; splat-transform 3.10.2
// stores the PLY's quaternions unnormalised (the extension asks for unit ones), so both are
// normalised before comparing.
void expectSameModel(const GaussianCloud& src, const GaussianCloud& dec)
{
    ASSERT_EQ(dec.size(), src.size());
    ASSERT_EQ(dec.shDegree, src.shDegree);
    const double f = std::ldexp(1.0, -23);
    for (std::size_t i = 0; i < src.size(); ++i) {
        for (int a = 0; a < 3; ++a) {
            ASSERT_NEAR(dec.means[3 * i + a], src.means[3 * i + a], std::fabs(src.means[3 * i + a]) * f) << i;
            ASSERT_NEAR(dec.logScales[3 * i + a], src.logScales[3 * i + a], 2 * f * (1 + std::fabs(src.logScales[3 * i + a])))
                << i;
        }
        ASSERT_NEAR(dec.opacities[i], src.opacities[i], 2 * logitTolerance(src.opacities[i])) << i;
        for (int j = 0; j < 3 * src.shCoeffs(); ++j) ASSERT_EQ(dec.shOf(i)[j], src.shOf(i)[j]) << i << " sh " << j;
        const Quatf q = src.rotation(i), r = dec.rotation(i);
        const double n = std::sqrt(double(q.w) * q.w + double(q.x) * q.x + double(q.y) * q.y + double(q.z) * q.z);
        const double m = std::sqrt(double(r.w) * r.w + double(r.x) * r.x + double(r.y) * r.y + double(r.z) * r.z);
        const double dot = (q.w * r.w + q.x * r.x + q.y * r.y + q.z * r.z) / (n * m);
        EXPECT_NEAR(std::fabs(dot), 1.0, 8 * f) << i;
    }
}

std::uint32_t le32(const std::string& d, std::size_t at)
{
    std::uint32_t v;
    std::memcpy(&v, d.data() + at, 4);
    return v;
}

// A glb with its JSON replaced (the BIN chunk kept).
std::string withJson(const std::string& glb, const nlohmann::json& doc)
{
    const std::size_t jsonLen = le32(glb, 12);
    const std::string bin = glb.substr(20 + jsonLen);
    std::string text = doc.dump();
    text.append((4 - text.size() % 4) % 4, ' ');
    std::string out = glb.substr(0, 12);
    const std::uint32_t len = std::uint32_t(20 + text.size() + bin.size()), tl = std::uint32_t(text.size());
    std::memcpy(&out[8], &len, 4);
    out.append(reinterpret_cast<const char*>(&tl), 4);
    out += "JSON";
    return out + text + bin;
}

nlohmann::json jsonOf(const std::string& glb) { return nlohmann::json::parse(glb.substr(20, le32(glb, 12))); }

void expectRefused(const TempDir& dir, const std::string& bytes, const std::string& part)
{
    const std::string path = dir.file("bad.glb");
    writeBytes(path, bytes);
    const std::string m = inputErrorMessage([&] { readGaussians(path); });
    EXPECT_NE(m.find(path), std::string::npos) << m;
    EXPECT_NE(m.find(part), std::string::npos) << "'" << part << "' not in: " << m;
}

} // namespace

TEST(Gltf, SplatTransformGlbMatchesSource)
{
    const GaussianCloud src = readGaussians(fixture("random200-sh3.ply"));
    ReadReport report;
    const GaussianCloud dec = readGaussians(fixture("random200-sh3.glb"), {}, &report);
    EXPECT_EQ(report.format, "glb");
    expectSameModel(src, dec);
}

TEST(Gltf, OwnGlbDecodesToSourceAndCarriesTheExtension)
{
    const GaussianCloud src = readGaussians(fixture("random200-sh3.ply"));
    const std::string glb = encodeGlb("x.glb", src);
    expectSameModel(src, readGaussiansFromBytes("x.glb", glb));
    TempDir dir; // the file is written in two pieces (no concatenated copy): the same bytes
    writeGaussians(dir.file("x.glb"), src);
    EXPECT_TRUE(fileBytes(dir.file("x.glb")) == glb);
    const nlohmann::json doc = jsonOf(glb);
    EXPECT_EQ(doc["extensionsUsed"][0], "KHR_gaussian_splatting");
    const auto& prim = doc["meshes"][0]["primitives"][0];
    EXPECT_EQ(prim["mode"], 0);
    EXPECT_EQ(prim["extensions"]["KHR_gaussian_splatting"]["kernel"], "ellipse");
    EXPECT_EQ(prim["extensions"]["KHR_gaussian_splatting"]["colorSpace"], "srgb_rec709_display");
    EXPECT_TRUE(prim["attributes"].contains("KHR_gaussian_splatting:SH_DEGREE_3_COEF_6"));
    EXPECT_FALSE(prim["attributes"].contains("KHR_gaussian_splatting:SH_DEGREE_4_COEF_0"));
    // The same axes as splat-transform's writer: the accessor bounds agree.
    const nlohmann::json ref = jsonOf(fileBytes(fixture("random200-sh3.glb")));
    for (int a = 0; a < 3; ++a) EXPECT_FLOAT_EQ(doc["accessors"][0]["min"][a].get<float>(), ref["accessors"][0]["min"][a].get<float>());
}

TEST(Gltf, BrokenFilesAreInputErrors)
{
    TempDir dir;
    const std::string glb = fileBytes(fixture("random200-sh3.glb"));
    expectRefused(dir, glb.substr(0, 10), "truncated");
    expectRefused(dir, glb.substr(0, glb.size() / 2), "truncated");
    std::string v = glb;
    v[4] = 1;
    expectRefused(dir, v, "version 1");
    expectRefused(dir, glb.substr(0, 20) + std::string(le32(glb, 12), '{') + glb.substr(20 + le32(glb, 12)), "JSON");
    nlohmann::json doc = jsonOf(glb);
    doc["accessors"][4]["count"] = 4000000000u; // opacity: a huge count cannot fit its buffer view
    expectRefused(dir, withJson(glb, doc), "does not fit");
    doc = jsonOf(glb);
    doc["meshes"][0]["primitives"][0]["attributes"].erase("KHR_gaussian_splatting:SH_DEGREE_2_COEF_3");
    expectRefused(dir, withJson(glb, doc), "SH degree 2 is partially defined");
    doc = jsonOf(glb);
    doc["meshes"][0]["primitives"][0]["extensions"]["KHR_gaussian_splatting"]["kernel"] = "cube";
    expectRefused(dir, withJson(glb, doc), "kernel 'cube'");
    doc = jsonOf(glb);
    doc["meshes"][0]["primitives"][0]["extensions"]["KHR_gaussian_splatting"]["kernel"] = 7;
    expectRefused(dir, withJson(glb, doc), "JSON");
    doc = jsonOf(glb);
    doc["nodes"][0]["scale"] = {1, 2, 1};
    expectRefused(dir, withJson(glb, doc), "not a rotation times a uniform positive scale");
    doc = jsonOf(glb);
    doc["nodes"][0]["children"] = {0};
    expectRefused(dir, withJson(glb, doc), "reached twice");
    doc = jsonOf(glb);
    for (int k = 1; k <= 300; ++k) { // a chain of 300 nodes above the mesh
        doc["nodes"][k - 1]["children"] = {k};
        doc["nodes"][k] = nlohmann::json::object();
    }
    expectRefused(dir, withJson(glb, doc), "deeper than 256");
    doc = jsonOf(glb);
    doc["meshes"][0]["primitives"][0].erase("extensions");
    expectRefused(dir, withJson(glb, doc), "without KHR_gaussian_splatting");
    doc = jsonOf(glb);
    doc["buffers"][0]["uri"] = "elsewhere.bin";
    expectRefused(dir, withJson(glb, doc), "external buffer");
}

// A parent node turning by 90 degrees about glTF's Y and scaling by 2, a child translating and
// placing the mesh: the splats are moved by parent * child in glTF space (centres, orientation, SH
// by the rotation, log scale + ln 2), then turned to graphdeco's axes.
TEST(Gltf, NodeTransformsAreApplied)
{
    const GaussianCloud src = readGaussians(fixture("random200-sh3.ply"));
    const std::string glb = encodeGlb("x.glb", src);
    nlohmann::json doc = jsonOf(glb);
    const double h = std::sqrt(0.5);
    doc["nodes"] = {{{"rotation", {0, h, 0, h}}, {"scale", {2, 2, 2}}, {"children", {1}}},
                    {{"translation", {1, 2, 3}}, {"mesh", 0}}};
    const GaussianCloud moved = readGaussiansFromBytes("moved.glb", withJson(glb, doc));
    ASSERT_EQ(moved.size(), src.size());
    // Expected, by hand: glTF coordinates of the source (x, y -> -x, -y), then R (x, y, z) ->
    // (z, y, -x) for 90 degrees about Y, times 2, plus 2 R (1, 2, 3), then back.
    GaussianCloud expected = src;
    for (std::size_t i = 0; i < src.size(); ++i) {
        const Vec3d p(-src.means[3 * i], -src.means[3 * i + 1], src.means[3 * i + 2]), t(1, 2, 3);
        const Vec3d q = (Vec3d(p.z, p.y, -p.x) + Vec3d(t.z, t.y, -t.x)) * 2.0;
        expected.setMean(i, Vec3f(float(-q.x), float(-q.y), float(q.z)));
        for (int a = 0; a < 3; ++a) expected.logScales[3 * i + a] += float(std::log(2.0));
    }
    for (std::size_t i = 0; i < src.size(); ++i) {
        for (int a = 0; a < 3; ++a) {
            ASSERT_NEAR(moved.means[3 * i + a], expected.means[3 * i + a], 1e-5) << i;
            ASSERT_NEAR(moved.logScales[3 * i + a], expected.logScales[3 * i + a], 1e-6) << i;
        }
    }
    // In graphdeco's axes the whole motion turns by Q: (x, y, z) -> (-z, y, x). Orientations are
    // Q R_i, and the view-dependent colour seen along Q d is the source's along d.
    const double qRows[9] = {0, 0, -1, 0, 1, 0, 1, 0, 0};
    const Mat3d q = Mat3d::fromRowMajor(qRows);
    const Vec3d dirs[3] = {{0.3, -0.5, 0.8}, {1, 0, 0}, {-0.2, 0.9, 0.1}};
    for (std::size_t i = 0; i < src.size(); ++i) {
        const Quatf a = src.rotation(i), b = moved.rotation(i);
        const Mat3d want = q * quatToMatrix(Quatd{a.w, a.x, a.y, a.z}), got = quatToMatrix(Quatd{b.w, b.x, b.y, b.z});
        for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 3; ++c) ASSERT_NEAR(got[r][c], want[r][c], 1e-5) << i;
        for (const Vec3d& d : dirs) {
            const Vec3d before = evalShSum<double>(3, src.shOf(i), d), after = evalShSum<double>(3, moved.shOf(i), q * d);
            for (int c = 0; c < 3; ++c) ASSERT_NEAR(after[c], before[c], 1e-5) << i;
        }
    }
}

TEST(Gltf, NaNAndOutOfRangeOpacityAreRefused)
{
    TempDir dir;
    GaussianCloud g = readGaussians(fixture("random200-sh3.ply"));
    std::string glb = encodeGlb("x.glb", g);
    const nlohmann::json doc = jsonOf(glb);
    const std::size_t bin = 20 + le32(glb, 12) + 8;
    const std::size_t pos = bin + doc["bufferViews"][0]["byteOffset"].get<std::size_t>();
    const std::size_t alpha = bin + doc["bufferViews"][doc["accessors"][3]["bufferView"].get<int>()]["byteOffset"].get<std::size_t>();
    std::string nan = glb;
    const float q = std::nanf(""), big = 1.5f;
    std::memcpy(&nan[pos + 12 * 5 + 4], &q, 4); // Gaussian 5's y
    expectRefused(dir, nan, "Gaussian 5: property 'y' is"); // -nan after the turn to graphdeco axes
    expectRefused(dir, nan, "nan (1 Gaussians hold");
    std::string range = glb;
    std::memcpy(&range[alpha + 4 * 9], &big, 4);
    expectRefused(dir, range, "Gaussian 9: opacity 1.5 is outside [0, 1]");
}
