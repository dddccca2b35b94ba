// The layout check that runs before OpenVDB reads a volume (vdb/VdbLayout.h): a cut or forged file
// is an InputError naming it, found from the lengths and offsets alone.
#include <gtest/gtest.h>

#include <openvdb/io/Stream.h>
#include <openvdb/openvdb.h>

#include <cstring>
#include <sstream>

#include "vdb/VdbLayout.h"
#include "vdb/VdbLibrary.h"
#include "vdb/Volume.h"
#include "core/Error.h"
#include "support/TestSupport.h"

namespace splatwarp {
namespace {

/// A small volume as OpenVDB writes it (io::File: grid offsets): density and a colour grid.
std::string smallVolume(const test::TempDir& dir)
{
    vdb::initialize();
    auto density = openvdb::FloatGrid::create(0.0f);
    density->setName("density");
    auto color = openvdb::Vec3SGrid::create(openvdb::Vec3s(0.0f));
    color->setName("color");
    for (int i = 0; i < 20; ++i) {
        density->tree().setValueOn(openvdb::Coord(i, i % 3, 0), 0.5f);
        color->tree().setValueOn(openvdb::Coord(i, i % 3, 0), openvdb::Vec3s(0.2f, 0.4f, 0.6f));
    }
    openvdb::MetaMap meta;
    meta.insertMeta("creator", openvdb::StringMetadata("someone"));
    openvdb::io::File(dir.file("v.vdb")).write({density, color}, meta);
    return test::fileBytes(dir.file("v.vdb"));
}

std::string layoutError(const std::string& bytes)
{
    std::istringstream in(bytes, std::ios::binary);
    return test::inputErrorMessage([&] { checkVdbLayout(in, bytes.size(), "x.vdb"); });
}

/// Where the first grid's descriptor starts: its name's length (7) and "density".
std::size_t densityDescriptor(const std::string& bytes)
{
    const std::size_t at = bytes.find(std::string("\x07\0\0\0density", 11));
    EXPECT_NE(at, std::string::npos);
    return at;
}

void put64(std::string& bytes, std::size_t at, std::int64_t v) { std::memcpy(&bytes[at], &v, 8); }

TEST(VdbLayout, AWholeFilePassesAndEveryCutIsNamed)
{
    test::TempDir dir;
    const std::string whole = smallVolume(dir);
    EXPECT_EQ(layoutError(whole), "");
    EXPECT_NO_THROW(readVolume(dir.file("v.vdb"), {}));
    // Every length from the magic on to one byte short: each needs bytes the file lacks.
    for (std::size_t cut = 8; cut < whole.size(); ++cut) {
        const std::string e = layoutError(whole.substr(0, cut));
        ASSERT_NE(e, "") << "cut at " << cut << " of " << whole.size();
        EXPECT_NE(e.find("x.vdb: "), std::string::npos) << e;
        EXPECT_NE(e.find("truncated or corrupt"), std::string::npos) << e;
    }
    EXPECT_NE(layoutError(whole.substr(0, whole.size() - 1)).find("grid 'color' ends at byte"), std::string::npos)
        << layoutError(whole.substr(0, whole.size() - 1));
    // Shorter than the magic, or another magic: OpenVDB's own refusal stands.
    EXPECT_EQ(layoutError(whole.substr(0, 7)), "");
    EXPECT_EQ(layoutError("ply\nformat binary_little_endian 1.0\n"), "");
}

TEST(VdbLayout, AStreamsFirstGridHeaderIsChecked)
{
    vdb::initialize();
    auto density = openvdb::FloatGrid::create(0.0f);
    density->setName("density");
    density->tree().setValueOn(openvdb::Coord(1, 2, 3), 0.5f);
    std::ostringstream stream(std::ios::binary);
    openvdb::io::Stream(stream).write(openvdb::GridCPtrVec{density});
    const std::string whole = stream.str();
    EXPECT_EQ(layoutError(whole), "");
    // Up to the end of the first grid's transform name (header, descriptor, metadata): each cut is named.
    const std::size_t transform = whole.find("UniformScaleMap");
    ASSERT_NE(transform, std::string::npos);
    for (std::size_t cut = 8; cut < transform + 15; ++cut)
        EXPECT_NE(layoutError(whole.substr(0, cut)), "") << "cut at " << cut;
}

TEST(VdbLayout, ForgedLengthsAndOffsetsAreRefusedBeforeAnyAllocation)
{
    test::TempDir dir;
    const std::string whole = smallVolume(dir);
    const std::size_t name = densityDescriptor(whole);
    // A name 4 GiB long (OpenVDB would allocate it).
    std::string forged = whole;
    forged[name] = forged[name + 1] = forged[name + 2] = char(0xff);
    EXPECT_NE(layoutError(forged).find("grid 0 name at byte"), std::string::npos) << layoutError(forged);
    // Offsets after the name (7), the type ("Tree_float_5_4_3") and the empty instance parent.
    const std::size_t offsets = name + 4 + 7 + 4 + 16 + 4;
    forged = whole;
    put64(forged, offsets + 16, std::int64_t(whole.size()) + 1);
    EXPECT_NE(layoutError(forged).find("grid 'density' ends at byte " + std::to_string(whole.size() + 1)), std::string::npos)
        << layoutError(forged);
    forged = whole;
    put64(forged, offsets, 0); // a grid that starts inside its own descriptor
    EXPECT_NE(layoutError(forged).find("offsets out of order"), std::string::npos) << layoutError(forged);
    // A volume's reader refuses the cut file by this check, naming the file (from-vdb, eval).
    std::ofstream(dir.file("cut.vdb"), std::ios::binary) << whole.substr(0, whole.size() - 1);
    const std::string e = test::inputErrorMessage([&] { readVolume(dir.file("cut.vdb"), {}); });
    EXPECT_NE(e.find(dir.file("cut.vdb") + ": grid 'color' ends at byte"), std::string::npos) << e;
}

// The delayed-load value (a mask byte and a compressed size per leaf) sizes OpenVDB's arrays by its
// own counts: a count one off failed an assertion in DelayedLoadMetadata.cc (exit 134), a high bit
// asked for gigabytes. Both are refused, naming the file; the volume is read without delayed
// loading anyway, so a sound value's contents are never trusted.
TEST(VdbLayout, ForgedDelayedLoadCountsAreRefused)
{
    test::TempDir dir;
    const std::string whole = smallVolume(dir);
    const std::size_t type = whole.find("__delayedload");
    ASSERT_NE(type, std::string::npos);
    const std::size_t count = type + 13 + 4; // after the type name and the value's size
    for (const std::uint32_t forged : {200u, 0x40000000u}) { // 3 leaves hold density's 20 voxels
        std::string bytes = whole;
        std::memcpy(&bytes[count], &forged, 4);
        std::ofstream(dir.file("f.vdb"), std::ios::binary) << bytes;
        const std::string e = test::inputErrorMessage([&] { readVolume(dir.file("f.vdb"), {}); });
        EXPECT_NE(e.find(dir.file("f.vdb") + ": grid 'density' metadata 'file_delayed_load'"), std::string::npos)
            << forged << ": " << e;
    }
}

} // namespace
// OpenVDB writes a fresh random UUID each time; settled, the same grids give the same bytes and
// the file still reads. The tag follows the content (another file, another tag), sits where
// OpenVDB reads it (vdb_print's "uuid"), and bytes without a VDB header are left alone.
TEST(VdbLayout, TheUuidFollowsTheContent)
{
    test::TempDir a, b;
    std::string first = smallVolume(a), second = smallVolume(b);
    ASSERT_NE(first, second) << "OpenVDB wrote the same UUID twice: this test no longer tests anything";
    settleVdbUuid(first);
    settleVdbUuid(second);
    EXPECT_EQ(first, second);

    settleVdbFileUuid(a.file("v.vdb"));
    EXPECT_EQ(test::fileBytes(a.file("v.vdb")), first);
    openvdb::io::File file(a.file("v.vdb"));
    file.open();
    const std::string uuid = file.getUniqueTag();
    EXPECT_EQ(uuid, first.substr(21, 36));
    EXPECT_EQ(uuid[14], '8'); // RFC 9562 version 8 (custom)
    EXPECT_EQ(layoutError(first), "");
    EXPECT_EQ(file.readGrid("density")->activeVoxelCount(), 20u);
    file.close();

    std::string other = first;
    other[other.size() - 1] ^= 1;
    settleVdbUuid(other);
    EXPECT_NE(other.substr(21, 36), uuid);

    std::string notVdb(100, 'x');
    settleVdbUuid(notVdb);
    EXPECT_EQ(notVdb, std::string(100, 'x'));
}

} // namespace splatwarp
