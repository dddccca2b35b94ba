/// OpenVDB point grids as a model format: written with Houdini's GSplat attribute names, read back
/// by readGaussians() in the source order, and by the CLI; broken files are InputErrors.
#include <gtest/gtest.h>

#include <openvdb/io/Stream.h>
#include <openvdb/openvdb.h>
#include <openvdb/points/PointDataGrid.h>

#include <cmath>
#include <filesystem>
#include <sstream>

#include "vdb/VdbLibrary.h"
#include "vdb/VdbPoints.h"
#include "core/Error.h"
#include "demo/DemoModels.h"
#include "io/GaussianIO.h"
#include "support/TestSupport.h"

using namespace splatwarp;
using namespace splatwarp::test;

namespace {

std::string fixture(const std::string& name) { return std::string(SPLATWARP_SOURCE_DIR) + "/tests/io/data/" + name; }

openvdb::points::PointDataGrid::Ptr firstPointGrid(const std::string& path)
{
    vdb::initialize();
    std::ifstream in(path, std::ios::binary);
    openvdb::io::Stream stream(in);
    for (const auto& g : *stream.getGrids())
        if (auto p = openvdb::gridPtrCast<openvdb::points::PointDataGrid>(g)) return p;
    return nullptr;
}

} // namespace

TEST(VdbPoints, RoundTripKeepsOrderAndValues)
{
    registerVdbPointFormat();
    TempDir dir;
    const GaussianCloud src = readGaussians(fixture("random200-sh3.ply"));
    const std::string path = dir.file("m.vdb");
    writeGaussians(path, src);
    writeGaussians(dir.file("again.vdb"), src);
    EXPECT_TRUE(fileBytes(path) == fileBytes(dir.file("again.vdb"))); // the UUID follows the content
    ReadReport report;
    const GaussianCloud back = readGaussians(path, {}, &report);
    EXPECT_EQ(report.format, "vdb-points");
    ASSERT_EQ(back.size(), src.size());
    ASSERT_EQ(back.shDegree, 3);
    const auto grid = firstPointGrid(path);
    ASSERT_TRUE(grid);
    // Positions are voxel-relative float32 offsets: off by float steps of the voxel and the centre.
    const double voxel = grid->transform().voxelSize()[0], f = std::ldexp(1.0, -23);
    for (std::size_t i = 0; i < src.size(); ++i) {
        for (int a = 0; a < 3; ++a) {
            ASSERT_NEAR(back.means[3 * i + a], src.means[3 * i + a], voxel * f + std::fabs(src.means[3 * i + a]) * f) << i;
            ASSERT_NEAR(back.logScales[3 * i + a], src.logScales[3 * i + a], 2 * f * (1 + std::fabs(src.logScales[3 * i + a])));
        }
        const double a = 1 / (1 + std::exp(-double(src.opacities[i])));
        ASSERT_NEAR(back.opacities[i], src.opacities[i], 4 * f / (a * (1 - a)) + std::fabs(src.opacities[i]) * f) << i;
        for (int j = 0; j < src.shStride(); ++j) ASSERT_EQ(back.shOf(i)[j], src.shOf(i)[j]) << i;
        const Quatf q = src.rotation(i), r = back.rotation(i);
        const double n = std::sqrt(double(q.w) * q.w + double(q.x) * q.x + double(q.y) * q.y + double(q.z) * q.z);
        EXPECT_NEAR(std::fabs(q.w * r.w + q.x * r.x + q.y * r.y + q.z * r.z) / n, 1.0, 8 * f) << i;
    }
}

TEST(VdbPoints, AttributesHaveHoudiniNamesAndTypes)
{
    TempDir dir;
    const GaussianCloud src = readGaussians(fixture("random200-sh3.ply"));
    writeVdbPoints(dir.file("m.vdb"), src);
    const auto grid = firstPointGrid(dir.file("m.vdb"));
    ASSERT_TRUE(grid);
    const auto leaf = grid->tree().cbeginLeaf();
    ASSERT_TRUE(leaf);
    const auto& d = leaf->attributeSet().descriptor();
    const std::pair<const char*, const char*> expected[] = {{"P", "vec3s"},        {"orient", "quats"},
                                                            {"scale", "vec3s"},    {"Cd", "vec3s"},
                                                            {"GS_Alpha", "float"}, {"GS_SPH_R", "float"},
                                                            {"GS_SPH_G", "float"}, {"GS_SPH_B", "float"},
                                                            {"id", "int32"}};
    for (const auto& [name, type] : expected) {
        const std::size_t pos = d.find(name);
        ASSERT_NE(pos, openvdb::points::AttributeSet::INVALID_POS) << name;
        EXPECT_EQ(d.valueType(pos), type) << name;
    }
    EXPECT_EQ(leaf->constAttributeArray("GS_SPH_R").stride(), 16u);
    openvdb::Index64 count = 0;
    for (auto l = grid->tree().cbeginLeaf(); l; ++l) count += l->pointCount();
    EXPECT_EQ(count, src.size());
}

TEST(VdbPoints, BrokenFilesAreInputErrorsAndVolumesAreNamed)
{
    registerVdbPointFormat();
    TempDir dir;
    writeVdbPoints(dir.file("m.vdb"), readGaussians(fixture("random200-sh3.ply")));
    const std::string bytes = fileBytes(dir.file("m.vdb"));
    for (std::size_t cut : {std::size_t(12), bytes.size() / 3, bytes.size() - 7}) {
        const std::string path = dir.file("cut.vdb");
        std::ofstream(path, std::ios::binary) << bytes.substr(0, cut);
        const std::string m = inputErrorMessage([&] { readGaussians(path); });
        EXPECT_NE(m.find(path), std::string::npos) << cut << ": " << m;
    }
    // A volume (a float grid, no points) is told apart.
    vdb::initialize();
    openvdb::FloatGrid::Ptr volume = openvdb::FloatGrid::create();
    volume->tree().setValue(openvdb::Coord(1, 2, 3), 1.0f);
    openvdb::io::File(dir.file("vol.vdb")).write({volume});
    const std::string m = inputErrorMessage([&] { readGaussians(dir.file("vol.vdb")); });
    EXPECT_NE(m.find("without a point grid"), std::string::npos) << m;
}

// Voxel offsets past the attribute arrays: an out-of-bounds read (an assertion, exit 134), or the
// cloud sized by them (a 12 KB file allocated 1.7 GB). Through the CLI: the old code aborted.
TEST(VdbPoints, LyingVoxelOffsetsAreRefused)
{
    TempDir dir;
    writeVdbPoints(dir.file("m.vdb"), readGaussians(fixture("random200-sh3.ply")));
    for (const openvdb::Index raise : {200000u, 30000000u}) {
        const auto grid = firstPointGrid(dir.file("m.vdb"));
        ASSERT_TRUE(grid);
        auto leaf = grid->tree().beginLeaf();
        leaf->setOffsetOnly(511, leaf->getValue(511) + raise);
        leaf->setValueOn(511);
        const std::string path = dir.file("lie.vdb");
        openvdb::io::File(path).write({grid});
        EXPECT_EQ(runCli("-q info " + path, dir.file("err")), 1) << raise;
        const std::string err = fileBytes(dir.file("err"));
        EXPECT_NE(err.find(path + ": point grid 'splats', leaf at "), std::string::npos) << err;
    }
}

// A file cut anywhere is an error naming it: OpenVDB's delayed loading read pages later, and a cut
// inside one failed an assertion in Page::readHeader (exit 134). Through the CLI for that reason.
TEST(VdbPoints, EveryCutOfAPointFileIsAnError)
{
    TempDir dir;
    writeVdbPoints(dir.file("m.vdb"), readGaussians(fixture("random200-sh3.ply")));
    const std::string bytes = fileBytes(dir.file("m.vdb"));
    const std::string path = dir.file("cut.vdb");
    for (std::size_t k = 1; k < 40; ++k) {
        const std::size_t cut = bytes.size() - bytes.size() * k / 120; // the last third: attribute pages
        std::ofstream(path, std::ios::binary) << bytes.substr(0, cut);
        EXPECT_EQ(runCli("-q info " + path, dir.file("err")), 1) << cut << ": " << fileBytes(dir.file("err"));
    }
}

// Centres at 1e12 were written at voxel coordinate -2^31 (int32), where OpenVDB's tools place them wrongly.
TEST(VdbPoints, CentresBeyondInt32VoxelCoordinatesAreRefused)
{
    test::TempDir dir;
    DemoModelOptions stripes; // a 4x1x1 bar: its points take voxels of 256 beside five at 1e12
    stripes.count = 500;
    GaussianCloud g = makeDemoModel("stripes", stripes);
    for (int i = 0; i < 5; ++i) g.means[3 * std::size_t(i)] = 1e12f;
    const std::string m = test::inputErrorMessage([&] { writeVdbPoints(dir.file("far.vdb"), g); });
    EXPECT_NE(m.find("beyond OpenVDB's 32-bit voxel coordinates"), std::string::npos) << m;
    EXPECT_FALSE(std::filesystem::exists(dir.file("far.vdb")));
}

TEST(VdbPoints, NaNInAnAttributeIsNamedWithItsGaussian)
{
    registerVdbPointFormat();
    TempDir dir;
    writeVdbPoints(dir.file("m.vdb"), readGaussians(fixture("random200-sh3.ply")));
    const auto grid = firstPointGrid(dir.file("m.vdb"));
    ASSERT_TRUE(grid);
    int changed = 0;
    for (auto leaf = grid->tree().beginLeaf(); leaf; ++leaf) {
        openvdb::points::AttributeHandle<openvdb::Int32> id(leaf->constAttributeArray("id"));
        openvdb::points::AttributeWriteHandle<openvdb::Vec3f> scale(leaf->attributeArray("scale"));
        for (auto it = leaf->beginIndexOn(); it; ++it)
            if (id.get(*it) == 5) scale.set(*it, openvdb::Vec3f(std::nanf(""), 1, 1)), ++changed;
    }
    ASSERT_EQ(changed, 1);
    openvdb::io::File(dir.file("nan.vdb")).write({grid});
    const std::string m = inputErrorMessage([&] { readGaussians(dir.file("nan.vdb")); });
    EXPECT_NE(m.find(dir.file("nan.vdb") + ": Gaussian 5: property 'scale_0' is nan"), std::string::npos) << m;
}

TEST(VdbPoints, CliConvertsBothWaysAndNeedsPointsFlag)
{
    TempDir dir;
    const std::string vdb = dir.file("m.vdb"), ply = dir.file("back.ply");
    EXPECT_EQ(runCli("-q convert " + fixture("random200-sh3.ply") + " " + vdb), 2);
    ASSERT_EQ(runCli("-q convert " + fixture("random200-sh3.ply") + " " + vdb + " --points"), 0);
    ASSERT_EQ(runCli("-q convert " + vdb + " " + ply), 0);
    const GaussianCloud a = readGaussians(fixture("random200-sh3.ply")), b = readGaussians(ply);
    ASSERT_EQ(a.size(), b.size());
    EXPECT_EQ(a.sh, b.sh);
    EXPECT_EQ(runCli("-q info " + vdb), 0);
}
