// Hostile volumes read by readVolume (vdb/Volume.h): each is an InputError naming the file, found
// before it costs memory or reaches an OpenVDB assertion.
#include <gtest/gtest.h>

#include <openvdb/openvdb.h>

#include <cmath>
#include <cstdio>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include "vdb/VdbLibrary.h"
#include "vdb/Volume.h"
#include "core/Error.h"
#include "support/TestSupport.h"

namespace splatwarp {
namespace {

openvdb::FloatGrid::Ptr densityGrid(float background = 0.0f, double voxelSize = 0.1)
{
    vdb::initialize();
    auto g = openvdb::FloatGrid::create(background);
    g->setName("density");
    g->setTransform(openvdb::math::Transform::createLinearTransform(voxelSize));
    return g;
}

/// An 8^3 block of `value` at the origin.
openvdb::FloatGrid::Ptr blob(float value = 0.5f, float background = 0.0f, double voxelSize = 0.1)
{
    auto g = densityGrid(background, voxelSize);
    g->tree().sparseFill(openvdb::CoordBBox(openvdb::Coord(0), openvdb::Coord(7)), value, true);
    return g;
}

std::string write(const test::TempDir& dir, const std::string& name, const openvdb::GridPtrVec& grids,
                  const openvdb::MetaMap& meta = {})
{
    const std::string path = dir.file(name);
    openvdb::io::File(path).write(grids, meta);
    return path;
}

constexpr double kEighth = 0.125;

std::string readError(const std::string& path, const VolumeReadOptions& o = {})
{
    return test::inputErrorMessage([&] { readVolume(path, o); });
}

// A level set whose inside is one inactive tile: its band is one voxel, but the conversion to fog
// makes the tile active (tester's lsi.vdb: a root tile of 4096^3 voxels, killed at 19.2 GB).
TEST(VolumeRead, LevelSetInsideTileIsCheckedAgainstTheMemoryLimit)
{
    test::TempDir dir;
    auto g = densityGrid(0.3f);
    g->setGridClass(openvdb::GRID_LEVEL_SET);
    // A root tile: sdfToFogVolume leaves an internal node's inactive tile inactive (no fog at all).
    g->tree().root().addTile(openvdb::Coord(0), -0.3f, /*active=*/false);
    g->tree().setValueOn(openvdb::Coord(-1), 0.05f);
    const std::string path = write(dir, "inside.vdb", {g});
    VolumeReadOptions o;
    o.memoryLimit = 64 << 20; // the band's voxel fits, the 4096^3 inside voxels (1 KB each) do not
    const std::string m = readError(path, o);
    EXPECT_NE(m.find(path + ": grid 'density': 68719476736 active voxels"), std::string::npos) << m;
    EXPECT_NE(m.find("--max-memory"), std::string::npos) << m;
}


// Opening a FIFO blocks until a writer comes: from-vdb hung forever. A writer is held open here so
// the old code reached its "cannot open" instead of hanging the test.
TEST(VolumeRead, AFifoIsRefusedBeforeItIsOpened)
{
    test::TempDir dir;
    const std::string path = dir.file("fifo.vdb");
    ASSERT_EQ(mkfifo(path.c_str(), 0600), 0);
    const int writer = open(path.c_str(), O_RDWR | O_NONBLOCK);
    ASSERT_GE(writer, 0);
    std::string m;
    try {
        readVolume(path);
    } catch (const Error& e) {
        m = e.what();
    }
    close(writer);
    EXPECT_NE(m.find(path + ": is not a regular file"), std::string::npos) << m;
}

// The fit works in float32: voxel sizes it cannot (1e-200 spun forever, NaN/0/negative were
// named without the file, 1e30 failed at the write) and voxels too far from the origin are named.
TEST(VolumeRead, VoxelSizesAndPositionsOutsideFloat32AreRefused)
{
    test::TempDir dir;
    const std::string eighth = test::fileBytes(write(dir, "eighth.vdb", {blob(0.5f, 0.0f, 0.125)}));
    for (const double size : {1e-200, 1e-30, 1e30, -0.1, 0.0}) {
        // OpenVDB refuses to make such transforms: the stored doubles are edited (the tester's way).
        std::string bytes = eighth;
        const std::string from(reinterpret_cast<const char*>(&kEighth), 8), to(reinterpret_cast<const char*>(&size), 8);
        for (std::size_t at = bytes.find(from); at != std::string::npos; at = bytes.find(from, at + 8)) bytes.replace(at, 8, to);
        const std::string path = dir.file("vs.vdb");
        std::ofstream(path, std::ios::binary) << bytes;
        const std::string m = readError(path);
        EXPECT_NE(m.find(path + ": grid 'density': "), std::string::npos) << size << ": " << m;
    }
    auto far = blob();
    far->tree().setValueOn(openvdb::Coord(100000000, 0, 0), 0.5f);
    const std::string path = write(dir, "far.vdb", {far});
    const std::string m = readError(path);
    EXPECT_NE(m.find("voxels from the origin"), std::string::npos) << m;
    EXPECT_NO_THROW(readVolume(write(dir, "ok.vdb", {blob(0.5f, 0.0f, 1e-3)})));
}

// Values the fit cannot square in float32 (3e38), a NaN or negative background, and a colour whose
// product with the density overflows were only "the energy at the start is not finite".
TEST(VolumeRead, OverflowingValuesAndBackgroundsNameTheFile)
{
    test::TempDir dir;
    const auto refused = [&](const openvdb::GridPtrVec& grids, const std::string& what) {
        const std::string path = write(dir, "v.vdb", grids);
        const std::string m = readError(path);
        EXPECT_NE(m.find(path + ": "), std::string::npos) << what << ": " << m;
        EXPECT_NE(m.find(what), std::string::npos) << m;
    };
    refused({blob(3e38f)}, "beyond");
    refused({blob(0.5f, std::nanf(""))}, "background nan");
    refused({blob(0.5f, -100.0f)}, "background -100");
    refused({blob(0.5f, 1e6f)}, "background 1e+06");
    auto inactive = blob();
    inactive->tree().setValueOff(openvdb::Coord(3), std::nanf("")); // sampled by the trilinear band
    refused({inactive}, "NaN/Inf");
    auto color = openvdb::Vec3SGrid::create(openvdb::Vec3s(0.0f));
    color->setName("color");
    color->setTransform(openvdb::math::Transform::createLinearTransform(0.1));
    color->tree().setValueOn(openvdb::Coord(1), openvdb::Vec3s(1e10f, 0.0f, 0.0f));
    refused({blob(1e9f), color}, "colour grid 'color' at voxel");
}

// Our own metadata is input: a filter strength of 1e30 smeared every Gaussian over the volume.
TEST(VolumeRead, OwnLambdaLpfIsBounded)
{
    test::TempDir dir;
    openvdb::MetaMap meta;
    meta.insertMeta("creator", openvdb::StringMetadata("splatwarp"));
    meta.insertMeta("lambda_lpf", openvdb::FloatMetadata(1e30f));
    const std::string path = write(dir, "own.vdb", {blob()}, meta);
    EXPECT_NE(readError(path).find(path + ": metadata lambda_lpf is 1e+30"), std::string::npos) << readError(path);
}

// OpenVDB reads the first of two grids of a name after a warning (on stdout); which was meant is
// not ours to guess.
TEST(VolumeRead, TwoGridsOfTheNameAskedForAreRefused)
{
    test::TempDir dir;
    const std::string path = write(dir, "two.vdb", {blob(0.5f), blob(0.9f)});
    const std::string m = readError(path);
    EXPECT_NE(m.find(path + ": 2 grids are named 'density'"), std::string::npos) << m;
}

// A grid named "den\x1b[31msity\n" reached the terminal raw in from-vdb's progress line and
// broke the --grid error over two lines.
TEST(VolumeRead, GridNamesAreShownOnOneLine)
{
    test::TempDir dir;
    auto g = blob();
    g->setName("den\x1b[31msity\n");
    const std::string path = write(dir, "w.vdb", {g, blob()});
    VolumeReadOptions o;
    o.grid = "nope\n";
    const std::string m = readError(path, o);
    EXPECT_NE(m.find("no FloatGrid named 'nope\\n'; grids: den\\x1b[31msity\\n (float), density (float)"), std::string::npos) << m;
    EXPECT_EQ(m.find('\n'), std::string::npos) << m;
}

// OpenVDB's log (log4cplus) wrote a coloured warning to stdout, inside `info --json`'s output.
TEST(VolumeRead, OpenVdbWarningsGoToStderr)
{
    test::TempDir dir;
    std::string bytes = test::fileBytes(write(dir, "v.vdb", {blob()}));
    bytes[9] ^= 1; // format version 224 -> 480: "unsupported VDB file format"
    std::ofstream(dir.file("f.vdb"), std::ios::binary) << bytes;
    const std::string cmd = std::string(SPLATWARP_CLI) + " -q from-vdb " + dir.file("f.vdb") + " -o " +
                            dir.file("x.ply") + " --no-fit >" + dir.file("out") + " 2>" + dir.file("err");
    std::system(cmd.c_str());
    EXPECT_EQ(test::fileBytes(dir.file("out")).find("WARN"), std::string::npos) << test::fileBytes(dir.file("out"));
    EXPECT_NE(test::fileBytes(dir.file("err")).find("OpenVDB WARN: unsupported VDB file format"), std::string::npos)
        << test::fileBytes(dir.file("err"));
}

} // namespace
} // namespace splatwarp
