#include <gtest/gtest.h>

#include <cmath>

#include "PlyTestFiles.h"
#include "core/Error.h"
#include "io/GaussianIO.h"
#include "support/TestSupport.h"

using namespace splatwarp;
using namespace splatwarp::test;

namespace {

GaussianCloud load(const std::string& path, ReadReport* report = nullptr) { return readGaussians(path, {}, report); }

bool hasNote(const ReadReport& r, const std::string& part)
{
    for (const std::string& n : r.notes)
        if (n.find(part) != std::string::npos) return true;
    return false;
}

} // namespace

TEST(PlyReader, WritePlyLoadsIdentically)
{
    TempDir dir;
    for (int degree = 0; degree <= 3; ++degree) {
        const GaussianCloud g = randomCloud(37, degree, 100 + degree);
        const std::string path = dir.file("w" + std::to_string(degree) + ".ply");
        writePly(path, g);
        ReadReport report;
        const GaussianCloud back = load(path, &report);
        EXPECT_TRUE(sameBits(g, back)) << "degree " << degree;
        EXPECT_EQ(report.format, "ply-binary-le");
        EXPECT_TRUE(report.notes.empty());
    }
}

TEST(PlyReader, LayoutVariantsLoadTheSameValues)
{
    TempDir dir;
    std::vector<PlyVariant> variants(8);
    variants[1].format = "ascii";
    variants[2].format = "binary_big_endian";
    variants[3].type = "double";
    variants[4].normals = false;
    variants[5].extraProperty = true;
    variants[6].extraElement = true;
    variants[7].reverseOrder = true;
    variants[7].format = "binary_big_endian";
    variants[7].type = "float64";
    for (int degree = 0; degree <= 3; ++degree) {
        const GaussianCloud g = randomCloud(23, degree, 7 + degree);
        for (std::size_t v = 0; v < variants.size(); ++v) {
            const std::string path = dir.file("v" + std::to_string(v) + ".ply");
            writeBytes(path, plyBytes(g, variants[v]));
            ReadReport report;
            const GaussianCloud back = load(path, &report);
            EXPECT_TRUE(sameBits(g, back)) << "degree " << degree << " variant " << v;
            EXPECT_EQ(back.shDegree, degree);
            EXPECT_EQ(hasNote(report, "'foo'"), variants[v].extraProperty) << v;
            EXPECT_EQ(hasNote(report, "'face'"), variants[v].extraElement) << v;
            const char* format = variants[v].format == "ascii"                ? "ply-ascii"
                                 : variants[v].format == "binary_big_endian" ? "ply-binary-be"
                                                                              : "ply-binary-le";
            EXPECT_EQ(report.format, format);
        }
    }
}

TEST(PlyReader, ExtraElementInAsciiIsSkipped)
{
    TempDir dir;
    PlyVariant v;
    v.format = "ascii";
    v.extraElement = true;
    v.extraProperty = true;
    const GaussianCloud g = randomCloud(5, 1, 3);
    writeBytes(dir.file("a.ply"), plyBytes(g, v));
    EXPECT_TRUE(sameBits(g, load(dir.file("a.ply"))));
}

TEST(PlyReader, IntegerTypesDecodeInBothByteOrders)
{
    TempDir dir;
    const char* types[] = {"char", "uchar", "short", "ushort", "int", "uint",
                           "int8", "uint8", "int16", "uint16", "int32", "uint32"};
    for (const char* type : types) {
        const bool isSigned = type[0] != 'u';
        GaussianCloud g = randomCloud(11, 0, 5);
        float next = isSigned ? -100.0f : 0.0f; // distinct integers inside every type's range
        for (auto* arr : {&g.means, &g.rotations, &g.logScales, &g.opacities, &g.sh})
            for (float& x : *arr) {
                x = next;
                next = next >= 120.0f ? (isSigned ? -100.0f : 0.0f) : next + 1.0f;
            }
        ReadOptions keep; // log-scales up to 120 overflow exp() in use; decoding is what is tested here
        keep.keepInvalid = true;
        for (const char* format : {"binary_little_endian", "binary_big_endian", "ascii"}) {
            PlyVariant v;
            v.type = type;
            v.format = format;
            writeBytes(dir.file("i.ply"), plyBytes(g, v));
            EXPECT_TRUE(sameBits(g, readGaussians(dir.file("i.ply"), keep))) << type << " " << format;
        }
    }
}

TEST(PlyReader, UnnormalisedQuaternionsAreKept)
{
    TempDir dir;
    GaussianCloud g = randomCloud(3, 0, 9);
    g.setRotation(0, Quatf{3.0f, 0.0f, 0.0f, 0.0f});
    g.setRotation(1, Quatf{0.1f, 0.2f, 0.0f, 0.0f});
    writeBytes(dir.file("q.ply"), plyBytes(g, PlyVariant{}));
    const GaussianCloud back = load(dir.file("q.ply"));
    EXPECT_EQ(back.rotations[0], 3.0f);
    EXPECT_EQ(back.rotations[4], 0.1f);
    EXPECT_EQ(back.rotations[5], 0.2f);
}

TEST(PlyReader, CrlfHeaderAndEmptyVertexElement)
{
    TempDir dir;
    std::string text = "ply\r\nformat ascii 1.0\r\nelement vertex 0\r\n";
    for (const std::string& n : graphdecoPropertyNames(0)) text += "property float " + n + "\r\n";
    text += "end_header\r\n";
    writeBytes(dir.file("e.ply"), text);
    const GaussianCloud g = load(dir.file("e.ply"));
    EXPECT_EQ(g.size(), 0u);
}
