/// SuperSplat compressed PLY written by the test (2 chunks, no chunk colour, SH degree 1 `sh`
/// element) against a naive double-precision decode of the chosen codes.
#include <gtest/gtest.h>

#include <cmath>

#include "PlyTestFiles.h"
#include "core/Error.h"
#include "io/GaussianIO.h"
#include "sh/SphericalHarmonics.h"
#include "support/TestSupport.h"

using namespace splatwarp;
using namespace splatwarp::test;

namespace {

constexpr std::size_t kN = 300; // two chunks of 256

struct Codes {
    std::uint32_t px, py, pz, sx, sy, sz, r, g, b, a, which, q0, q1, q2;
    std::uint8_t sh[9];
};

Codes codesOf(std::size_t i)
{
    Codes c{};
    c.px = (i * 7) % 2048, c.py = (i * 13) % 1024, c.pz = (i * 29 + 5) % 2048;
    c.sx = (i * 3) % 2048, c.sy = (i * 11) % 1024, c.sz = 2047 - (i % 2048);
    c.r = i % 256, c.g = (i * 5) % 256, c.b = 255 - i % 256, c.a = (i * 17) % 256;
    c.which = i % 4, c.q0 = (i * 31) % 1024, c.q1 = 512, c.q2 = (1023 - i * 3 % 1024);
    for (int k = 0; k < 9; ++k) c.sh[k] = std::uint8_t((i * (k + 1) * 37) % 256);
    return c;
}

const float kMin[2][6] = {{-1, -2, -3, -9, -8, -7}, {0.5f, 1, 2, -4, -5, -6}};
const float kMax[2][6] = {{1, 2, 3, 1, 0.5f, -1}, {1.5f, 3, 2.5f, 0, -1, -2}};

std::string compressedPly(std::size_t chunks)
{
    std::string s = "ply\nformat binary_little_endian 1.0\ncomment SuperSplat-style test file\n";
    s += "element chunk " + std::to_string(chunks) + "\n";
    for (const char* p : {"min_x", "min_y", "min_z", "max_x", "max_y", "max_z", "min_scale_x", "min_scale_y",
                          "min_scale_z", "max_scale_x", "max_scale_y", "max_scale_z"})
        s += std::string("property float ") + p + "\n";
    s += "element vertex " + std::to_string(kN) + "\n";
    for (const char* p : {"packed_position", "packed_rotation", "packed_scale", "packed_color"})
        s += std::string("property uint ") + p + "\n";
    s += "element sh " + std::to_string(kN) + "\n";
    for (int k = 0; k < 9; ++k) s += "property uchar f_rest_" + std::to_string(k) + "\n";
    s += "end_header\n";
    for (std::size_t c = 0; c < chunks; ++c) {
        const std::size_t ci = std::min<std::size_t>(c, 1);
        for (int a = 0; a < 3; ++a) appendScalar<float>(s, kMin[ci][a], false);
        for (int a = 0; a < 3; ++a) appendScalar<float>(s, kMax[ci][a], false);
        for (int a = 0; a < 3; ++a) appendScalar<float>(s, kMin[ci][3 + a], false);
        for (int a = 0; a < 3; ++a) appendScalar<float>(s, kMax[ci][3 + a], false);
    }
    for (std::size_t i = 0; i < kN; ++i) {
        const Codes c = codesOf(i);
        appendScalar<std::uint32_t>(s, (c.px << 21) | (c.py << 11) | c.pz, false);
        appendScalar<std::uint32_t>(s, (c.which << 30) | (c.q0 << 20) | (c.q1 << 10) | c.q2, false);
        appendScalar<std::uint32_t>(s, (c.sx << 21) | (c.sy << 11) | c.sz, false);
        appendScalar<std::uint32_t>(s, (c.r << 24) | (c.g << 16) | (c.b << 8) | c.a, false);
    }
    for (std::size_t i = 0; i < kN; ++i) s.append(reinterpret_cast<const char*>(codesOf(i).sh), 9);
    return s;
}

} // namespace

TEST(CompressedPly, SyntheticFileMatchesNaiveDecode)
{
    TempDir dir;
    const std::string path = dir.file("c.ply");
    writeBytes(path, compressedPly(2));
    ReadReport report;
    const GaussianCloud g = readGaussians(path, {}, &report);
    EXPECT_EQ(report.format, "ply-compressed");
    ASSERT_EQ(g.size(), kN);
    ASSERT_EQ(g.shDegree, 1);
    double worst = 0;
    const auto near = [&](float got, double want) { worst = std::max(worst, std::abs(double(got) - want)); };
    for (std::size_t i = 0; i < kN; ++i) {
        const Codes c = codesOf(i);
        const int ci = i < 256 ? 0 : 1;
        const double pos[3] = {c.px / 2047.0, c.py / 1023.0, c.pz / 2047.0};
        const double sc[3] = {c.sx / 2047.0, c.sy / 1023.0, c.sz / 2047.0};
        for (int a = 0; a < 3; ++a) {
            near(g.means[3 * i + a], kMin[ci][a] + (kMax[ci][a] - kMin[ci][a]) * pos[a]);
            near(g.logScales[3 * i + a], kMin[ci][3 + a] + (kMax[ci][3 + a] - kMin[ci][3 + a]) * sc[a]);
        }
        const std::uint32_t rgb[3] = {c.r, c.g, c.b};
        for (int a = 0; a < 3; ++a) near(g.sh[i * 12 + a], (rgb[a] / 255.0 - 0.5) / kShC0);
        const double alpha = std::min(std::max(c.a / 255.0, 1e-6), 1.0 - 1e-6);
        near(g.opacities[i], std::log(alpha / (1 - alpha)));
        // Smallest three in [-1/sqrt2, 1/sqrt2]; the largest from the unit norm.
        const double s = std::sqrt(2.0);
        const double abc[3] = {(c.q0 / 1023.0 - 0.5) * s, (c.q1 / 1023.0 - 0.5) * s, (c.q2 / 1023.0 - 0.5) * s};
        const double big = std::sqrt(std::max(0.0, 1 - abc[0] * abc[0] - abc[1] * abc[1] - abc[2] * abc[2]));
        for (std::uint32_t k = 0, j = 0; k < 4; ++k) near(g.rotations[4 * i + k], k == c.which ? big : abc[j++]);
        // f_rest_{c*3 + j-1} = coefficient j of channel c.
        for (int ch = 0; ch < 3; ++ch)
            for (int j = 1; j < 4; ++j) {
                const int q = c.sh[ch * 3 + j - 1];
                const double u = q == 0 ? 0.0 : q == 255 ? 1.0 : (q + 0.5) / 256.0;
                near(g.sh[i * 12 + 3 * j + ch], (u - 0.5) * 8.0);
            }
    }
    std::printf("synthetic compressed worst |diff| %g\n", worst);
    EXPECT_LE(worst, 1e-6); // float32 rounding of values below 16
}

TEST(CompressedPly, ChunkCountMustMatch)
{
    TempDir dir;
    const std::string path = dir.file("c.ply");
    writeBytes(path, compressedPly(1)); // header says 1 chunk for 300 vertices
    try {
        readGaussians(path);
        ADD_FAILURE() << "no error";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("1 chunk records for 300 vertices"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find(path), std::string::npos);
    }
    const std::string out = dir.file("o.ply");
    EXPECT_EQ(runCli("convert " + path + " " + out), 1);
    EXPECT_FALSE(std::filesystem::exists(out));
}
