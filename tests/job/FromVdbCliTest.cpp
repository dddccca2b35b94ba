#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

#include <nlohmann/json.hpp>

#include <openvdb/openvdb.h>

#include "vdb/Volume.h"
#include "support/VdbFileReader.h"
#include "support/TestSupport.h"

namespace splatwarp {
namespace {

using test::runCli;
using test::TempDir;

std::string slurp(const std::string& path)
{
    std::ifstream in(path);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
}

DenseGrid smallFog(const std::string& name = "density")
{
    DenseGrid d;
    d.name = name;
    d.voxelSize = 0.1;
    d.dims[0] = d.dims[1] = d.dims[2] = 8;
    for (int i = 0; i < 512; ++i) d.values.push_back(float(((i * 37) % 11) / 10.0));
    return d;
}

/// Run from-vdb on `vdb`; expect exit 1, a message naming the file and `name`, and no outputs.
void expectRefused(const TempDir& dir, const std::string& vdb, const std::string& name, const std::string& extra = "")
{
    const std::string log = dir.file("log.txt");
    EXPECT_EQ(runCli("from-vdb " + vdb + " -o " + dir.file("out.ply") + " " + extra, log), 1) << slurp(log);
    const std::string text = slurp(log);
    EXPECT_NE(text.find(vdb), std::string::npos) << text;
    EXPECT_NE(text.find(name), std::string::npos) << text;
    EXPECT_FALSE(std::filesystem::exists(dir.file("out.ply")));
    EXPECT_FALSE(std::filesystem::exists(dir.file("out.report.json")));
}

TEST(FromVdbCli, BadInputsExitOneAndWriteNothing)
{
    TempDir dir;
    std::ofstream(dir.file("text.vdb")) << "not a volume\n";
    expectRefused(dir, dir.file("text.vdb"), "not an OpenVDB file");

    DenseGrid vel = smallFog("vel");
    vel.vector = true;
    writeDenseGrids(dir.file("novalue.vdb"), {vel});
    expectRefused(dir, dir.file("novalue.vdb"), "vel (vec3s)");

    DenseGrid empty = smallFog();
    std::fill(empty.values.begin(), empty.values.end(), 0.0f);
    writeDenseGrids(dir.file("empty.vdb"), {empty});
    expectRefused(dir, dir.file("empty.vdb"), "'density' has no active voxels");

    DenseGrid nan = smallFog();
    nan.values[77] = std::numeric_limits<float>::quiet_NaN();
    writeDenseGrids(dir.file("nan.vdb"), {nan});
    expectRefused(dir, dir.file("nan.vdb"), "'density' has 1 NaN/Inf");

    DenseGrid huge = smallFog();
    huge.fillVoxels = 4096; // 6.9e10 voxels as one sparse tile: tiny on disk, far beyond memory
    writeDenseGrids(dir.file("huge.vdb"), {huge});
    expectRefused(dir, dir.file("huge.vdb"), "'density'");

    DenseGrid negative = smallFog();
    negative.values[5] = -0.5f;
    writeDenseGrids(dir.file("negative.vdb"), {negative});
    expectRefused(dir, dir.file("negative.vdb"), "'density' has negative values");

    // --max-memory: the grid's voxels (the least its fit needs) before it is read, then its
    // training samples with their band; --no-fit needs neither.
    writeDenseGrids(dir.file("fog.vdb"), {smallFog()});
    expectRefused(dir, dir.file("fog.vdb"), "need at least", "--max-memory 64K"); // 8 samples a voxel: ~1 KB
    expectRefused(dir, dir.file("fog.vdb"), "training samples (1^3 per voxel, with a band of 2)",
                  "--max-memory 64K --samples-per-voxel 1"); // 124 B a voxel, and the process holds more than 64K
    EXPECT_EQ(runCli("-q from-vdb " + dir.file("fog.vdb") + " -o " + dir.file("base.ply") + " --no-fit --max-memory 64K"), 0);
    EXPECT_EQ(runCli("from-vdb " + dir.file("fog.vdb") + " -o " + dir.file("x.ply") + " --max-memory lots"), 2);

    writeDenseGrids(dir.file("two.vdb"), {smallFog("a"), smallFog("b")});
    expectRefused(dir, dir.file("two.vdb"), "a (float), b (float)");
    expectRefused(dir, dir.file("two.vdb"), "'c'", "--grid c");
    EXPECT_EQ(runCli("from-vdb " + dir.file("two.vdb")), 2); // no -o: usage error

    // Our own file (to-vdb) whose filter metadata was edited into nonsense.
    ASSERT_EQ(runCli("-q sample stripes --count 300 -o " + dir.file("m.ply")), 0);
    ASSERT_EQ(runCli("-q to-vdb " + dir.file("m.ply") + " -o " + dir.file("own.vdb") + " --cells 8 --device cpu"), 0);
    for (const float bad : {std::numeric_limits<float>::quiet_NaN(), -1.0f, std::numeric_limits<float>::infinity()}) {
        test::setFileMetadata(dir.file("own.vdb"), "lambda_lpf", bad);
        expectRefused(dir, dir.file("own.vdb"), "lambda_lpf");
    }
}

// A level set (negative inside) becomes fog: interior 1, a note in the report, nothing refused.
TEST(FromVdbCli, LevelSetIsConvertedToFogWithANote)
{
    DenseGrid sdf;
    sdf.voxelSize = 0.1;
    sdf.levelSet = true;
    for (int a = 0; a < 3; ++a) {
        sdf.origin[a] = -6;
        sdf.dims[a] = 13;
    }
    for (int k = -6; k <= 6; ++k)
        for (int j = -6; j <= 6; ++j)
            for (int i = -6; i <= 6; ++i) {
                const float d = 0.1f * (std::sqrt(float(i * i + j * j + k * k)) - 4.0f); // sphere of radius 4 voxels
                sdf.values.push_back(d < 0.3f ? std::max(d, -0.3f) : 0.0f); // inside negative, outside band of 3 voxels
            }
    TempDir dir;
    DenseGrid bandOnly = sdf; // positive values only: no inside, so the fog is empty
    for (float& v : bandOnly.values) v = std::max(v, 0.0f);
    writeDenseGrids(dir.file("band.vdb"), {bandOnly});
    expectRefused(dir, dir.file("band.vdb"), "'density' has no active voxels after the conversion");
    writeDenseGrids(dir.file("ls.vdb"), {sdf});
    const std::string log = dir.file("log.txt");
    ASSERT_EQ(runCli("from-vdb " + dir.file("ls.vdb") + " -o " + dir.file("ls.ply") + " --no-fit --eval-points 2000", log), 0)
        << slurp(log);
    const nlohmann::json r = nlohmann::json::parse(slurp(dir.file("ls.report.json")));
    EXPECT_TRUE(r["input"]["levelSet"].get<bool>());
    EXPECT_GE(r["input"]["min"].get<double>(), 0.0);
    EXPECT_NEAR(r["input"]["max"].get<double>(), 1.0, 1e-6);
    EXPECT_NE(r["input"]["notes"].dump().find("level set converted"), std::string::npos) << r["input"]["notes"].dump();
    EXPECT_GT(r["gaussians"]["final"].get<int>(), 0);
}

TEST(FromVdbCli, WritesModelReportAndPicture)
{
    TempDir dir;
    writeDenseGrids(dir.file("fog.vdb"), {smallFog("smoke")});
    const std::string log = dir.file("log.txt");
    ASSERT_EQ(runCli("from-vdb " + dir.file("fog.vdb") + " -o " + dir.file("fog.ply") +
                         " --iterations 5 --render --size 64 --eval-points 2000 --device cpu",
                     log),
              0)
        << slurp(log);
    EXPECT_TRUE(std::filesystem::exists(dir.file("fog.ply")));
    EXPECT_TRUE(std::filesystem::exists(dir.file("fog.png")));
    const nlohmann::json r = nlohmann::json::parse(slurp(dir.file("fog.report.json")));
    EXPECT_EQ(r["input"]["grid"], "smoke");
    EXPECT_EQ(r["as"], "extinction");
    EXPECT_EQ(r["gaussians"]["budget"], (512u - 47u) / 8u); // 47 of the 512 values are 0 (i % 11 == 0)
    EXPECT_TRUE(r["heldOut"].contains("fit"));
    // eval --volume judges the written model with the same yardstick as the report.
    ASSERT_EQ(runCli("eval --volume " + dir.file("fog.vdb") + " --model " + dir.file("fog.ply") +
                         " --points 2000 --json", dir.file("eval.json")), 0) << slurp(dir.file("eval.json"));
    const nlohmann::json e = nlohmann::json::parse(slurp(dir.file("eval.json")));
    EXPECT_NEAR(double(e["opacity"]), double(r["heldOut"]["fit"]["opacity"]), 0.02);
}

} // namespace
} // namespace splatwarp

namespace splatwarp {
namespace {

// No output may be the input or another output; a failed write leaves none of them.
TEST(FromVdbCli, OutputsThatAreTheInputOrEachOtherAreRefused)
{
    TempDir dir;
    writeDenseGrids(dir.file("m.vdb"), {smallFog()});
    const std::string before = slurp(dir.file("m.vdb"));
    const std::string log = dir.file("log.txt");
    const std::string fit = " --iterations 2 --eval-points 500 --device cpu";
    EXPECT_EQ(runCli("from-vdb " + dir.file("m.vdb") + " -o " + dir.file("m.vdb") + fit, log), 1);
    EXPECT_NE(slurp(log).find("is also an input of this command"), std::string::npos) << slurp(log);
    EXPECT_EQ(runCli("from-vdb " + dir.file("m.vdb") + " -o " + dir.file("o.ply") + " --report " + dir.file("m.vdb") + fit, log), 1);
    EXPECT_NE(slurp(log).find("is also an input of this command"), std::string::npos) << slurp(log);
    EXPECT_EQ(slurp(dir.file("m.vdb")), before);
    EXPECT_EQ(runCli("from-vdb " + dir.file("m.vdb") + " -o " + dir.file("o.ply") + " --report " + dir.file("o.ply") + fit, log), 1);
    EXPECT_NE(slurp(log).find("is also another output of this command"), std::string::npos) << slurp(log);
    EXPECT_EQ(runCli("from-vdb " + dir.file("m.vdb") + " -o " + dir.file("o.png") + " --render --size 16" + fit, log), 1);
    EXPECT_NE(slurp(log).find("is also another output of this command"), std::string::npos) << slurp(log);
    // The report cannot be written (its folder is a file): no model either.
    std::ofstream(dir.file("afile")) << "x";
    EXPECT_EQ(runCli("from-vdb " + dir.file("m.vdb") + " -o " + dir.file("o.ply") + " --report " + dir.file("afile/r.json") + fit, log), 1);
    EXPECT_FALSE(std::filesystem::exists(dir.file("o.ply")));
    for (const char* bad : {"--gaussians -1", "--gaussians 2e19", "--lr-position -1e9", "--density-scale -1"})
        EXPECT_EQ(runCli("from-vdb " + dir.file("m.vdb") + " -o " + dir.file("o.ply") + " " + bad), 2) << bad;
}

TEST(FromVdbCli, ForgedOwnMetadataCutFilesAndZeroVolumesExitOne)
{
    TempDir dir;
    { // active voxels that are all zero: nothing to fit (it wrote a 0-Gaussian PLY)
        openvdb::initialize();
        openvdb::FloatGrid::Ptr zero = openvdb::FloatGrid::create(0.0f);
        zero->setName("density");
        for (int i = 0; i < 8; ++i) zero->tree().setValueOn(openvdb::Coord(i, 0, 0), 0.0f);
        openvdb::io::File(dir.file("zero.vdb")).write({zero});
    }
    expectRefused(dir, dir.file("zero.vdb"), "holds only zeros");
    ASSERT_EQ(runCli("-q sample stripes --count 300 -o " + dir.file("m.ply")), 0);
    ASSERT_EQ(runCli("-q to-vdb " + dir.file("m.ply") + " -o " + dir.file("own.vdb") + " --cells 8 --sh-grids --device cpu"), 0);
    for (const std::int32_t degree : {-1, 2147483647, 4}) {
        test::setFileMetadataInt(dir.file("own.vdb"), "sh_degree", degree);
        expectRefused(dir, dir.file("own.vdb"), "metadata sh_degree is " + std::to_string(degree));
    }
    test::setFileMetadataInt(dir.file("own.vdb"), "sh_degree", 3); // the stripes are degree 1: sh_4.. are missing
    expectRefused(dir, dir.file("own.vdb"), "no Vec3S grid sh_4");
    // A file cut short names itself instead of OpenVDB's "KeyError: Map is not registered".
    test::setFileMetadataInt(dir.file("own.vdb"), "sh_degree", 1);
    const std::string whole = slurp(dir.file("own.vdb"));
    for (const std::size_t cut : {whole.size() - 1, whole.size() / 2, std::size_t(200)}) {
        std::ofstream(dir.file("cut.vdb"), std::ios::binary) << whole.substr(0, cut);
        expectRefused(dir, dir.file("cut.vdb"), "cut.vdb");
        EXPECT_EQ(slurp(dir.file("log.txt")).find("internal error"), std::string::npos) << slurp(dir.file("log.txt"));
    }
}

} // namespace
} // namespace splatwarp
