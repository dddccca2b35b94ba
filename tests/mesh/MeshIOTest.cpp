#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <jpeglib.h>

#include "core/AtomicFile.h"
#include "core/Error.h"
#include "image/ImageIO.h"
#include "image/TextureIO.h"
#include "mesh/MeshIO.h"
#include "mesh/MeshRasterizer.h"
#include "mesh/BadMeshes.h"
#include "support/TestSupport.h"

namespace splatwarp {
namespace {

/// A 2x2-texel image with four distinct 8-bit colours.
Image fourTexels()
{
    Image t(2, 2, 3);
    const float v[12] = {200, 20, 20, 20, 200, 20, 20, 20, 200, 240, 240, 40};
    for (int i = 0; i < 12; ++i) t.pixels[std::size_t(i)] = v[i] / 255.0f;
    return t;
}

/// Write an RGB image as a baseline JPEG at the highest quality.
void writeJpeg(const std::string& path, const Image& image)
{
    jpeg_compress_struct info{};
    jpeg_error_mgr err{};
    info.err = jpeg_std_error(&err);
    jpeg_create_compress(&info);
    FILE* f = std::fopen(path.c_str(), "wb");
    ASSERT_NE(f, nullptr);
    jpeg_stdio_dest(&info, f);
    info.image_width = JDIMENSION(image.width);
    info.image_height = JDIMENSION(image.height);
    info.input_components = 3;
    info.in_color_space = JCS_RGB;
    jpeg_set_defaults(&info);
    jpeg_set_quality(&info, 100, TRUE);
    info.comp_info[0].h_samp_factor = info.comp_info[0].v_samp_factor = 1; // 4:4:4, no chroma blur
    jpeg_start_compress(&info, TRUE);
    std::vector<unsigned char> row(std::size_t(image.width) * 3);
    for (int y = 0; y < image.height; ++y) {
        for (int i = 0; i < image.width * 3; ++i) row[std::size_t(i)] = (unsigned char)std::lround(image.pixels[std::size_t(y * image.width * 3 + i)] * 255);
        JSAMPROW r = row.data();
        jpeg_write_scanlines(&info, &r, 1);
    }
    jpeg_finish_compress(&info);
    jpeg_destroy_compress(&info);
    std::fclose(f);
}

/// A unit quad in the plane z = 0 with UVs, using material `quad` of `mtl` (when given).
std::string quadObj(const std::string& mtl)
{
    std::string s = mtl.empty() ? "" : "mtllib " + mtl + "\nusemtl quad\n";
    return s + "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3 4/4\n";
}

void expectErrorNaming(const std::string& path, const std::string& name)
{
    try {
        readMesh(path);
        FAIL() << "expected an error for " << path;
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
    }
}

TEST(MeshIOTest, ObjWithMtlAndPngOrJpegTexture)
{
    test::TempDir dir;
    writePng(dir.file("tex.png"), fourTexels());
    writeJpeg(dir.file("tex.jpg"), fourTexels());
    for (const char* tex : {"tex.png", "tex.jpg"}) {
        writeFileAtomic(dir.file("quad.mtl"), std::string("newmtl quad\nKd 1 1 1\nmap_Kd ") + tex + "\n");
        writeFileAtomic(dir.file("quad.obj"), quadObj("quad.mtl"));
        const TriangleMesh m = readMesh(dir.file("quad.obj"));
        ASSERT_EQ(m.triangleCount(), 2u) << tex; // the quad is triangulated
        ASSERT_EQ(m.textures.size(), 1u);
        EXPECT_EQ(m.textures[0].width, 2);
        // The texel at the top left of the picture is at uv (0, 1): the first stored row.
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(m.textures[0].at(0, 0, c), fourTexels().at(0, 0, c), 4.0 / 255) << tex;
        // Seen from z = -4 looking at +z, up = +y: the top-left quadrant shows texel (0, 0).
        const Camera cam = Camera::lookAt(Vec3d(0, 0, -4), Vec3d(0, 0, 0), Vec3d(0, 1, 0), 40.0, 64, 64);
        const Image img = renderMesh(m, cam);
        EXPECT_FLOAT_EQ(img.at(32, 32, 3), 1.0f);
        EXPECT_FLOAT_EQ(img.at(0, 0, 3), 0.0f);
    }
}

// libjpeg only warns on a file cut short and fills the rest with grey: a cut texture or training
// picture is refused instead, by name.
TEST(MeshIOTest, ACutJpegIsRefused)
{
    test::TempDir dir;
    Image big(64, 64, 3);
    for (std::size_t i = 0; i < big.pixels.size(); ++i) big.pixels[i] = float((i * 37) % 251) / 255.0f;
    writeJpeg(dir.file("whole.jpg"), big);
    EXPECT_EQ(readTexture(dir.file("whole.jpg")).width, 64);
    const std::string bytes = test::fileBytes(dir.file("whole.jpg"));
    writeFileAtomic(dir.file("cut.jpg"), bytes.substr(0, bytes.size() / 2));
    const std::string e = test::inputErrorMessage([&] { readTexture(dir.file("cut.jpg")); });
    EXPECT_NE(e.find("cut.jpg: corrupt JPEG: Premature end of JPEG file"), std::string::npos) << e;
}

// A header declaring more pixels than the data holds: past kMaxImageSide refused by its size (a
// 631-byte file declaring 65000x65000 cost 12 GB), below it at the first row that is not there,
// where libjpeg would fill the rest with grey (its data ends at the end-of-image marker).
TEST(MeshIOTest, AForgedJpegSizeIsRefused)
{
    test::TempDir dir;
    writeJpeg(dir.file("small.jpg"), fourTexels());
    const std::string bytes = test::fileBytes(dir.file("small.jpg"));
    const std::size_t sof = bytes.find("\xFF\xC0"); // baseline frame: length, precision, height, width
    ASSERT_NE(sof, std::string::npos);
    const auto declaring = [&](const std::string& name, int side) {
        std::string s = bytes;
        for (const std::size_t at : {sof + 5, sof + 7}) {
            s[at] = char(side >> 8);
            s[at + 1] = char(side & 0xFF);
        }
        writeFileAtomic(dir.file(name), s);
        return test::inputErrorMessage([&] { readTexture(dir.file(name)); });
    };
    std::string e = declaring("huge.jpg", 65000);
    EXPECT_NE(e.find("huge.jpg: an image of 65000x65000 pixels"), std::string::npos) << e;
    e = declaring("big.jpg", 16000);
    EXPECT_NE(e.find("big.jpg: corrupt JPEG: Corrupt JPEG data: premature end of data segment"), std::string::npos) << e;
}

// readTextureSize() gives what readTexture() decodes, from the header alone: PNG (RGB, RGBA) and
// JPEG, one with a large segment before its frame header; a file cut before its size, a forged
// size and a file of neither kind are refused naming the file.
TEST(MeshIOTest, APicturesSizeIsReadFromItsHeaderAlone)
{
    test::TempDir dir;
    writePng(dir.file("rgb.png"), Image(37, 23, 3, 0.5f));
    writePng(dir.file("rgba.png"), Image(5, 41, 4, 0.25f));
    writeJpeg(dir.file("plain.jpg"), Image(41, 19, 3, 0.75f));
    std::string jpeg = test::fileBytes(dir.file("plain.jpg"));
    const std::string comment = "\xFF\xFE\x13\x8A" + std::string(5000, 'c'); // COM segment, length 5002
    writeFileAtomic(dir.file("comment.jpg"), jpeg.substr(0, 2) + comment + jpeg.substr(2));
    for (const char* name : {"rgb.png", "rgba.png", "plain.jpg", "comment.jpg"}) {
        const Image decoded = readTexture(dir.file(name));
        const PictureSize size = readTextureSize(dir.file(name));
        EXPECT_EQ(size.width, decoded.width) << name;
        EXPECT_EQ(size.height, decoded.height) << name;
    }
    writeFileAtomic(dir.file("cut.jpg"), jpeg.substr(0, 2) + comment.substr(0, 3000));
    std::string e = test::inputErrorMessage([&] { readTextureSize(dir.file("cut.jpg")); });
    EXPECT_NE(e.find("cut.jpg: corrupt JPEG: the file ends before its frame header"), std::string::npos) << e;
    std::string png = test::fileBytes(dir.file("rgb.png"));
    png[16] = char(0x00), png[17] = char(0x00), png[18] = char(0xFD), png[19] = char(0xE8); // width 65000
    writeFileAtomic(dir.file("wide.png"), png);
    e = test::inputErrorMessage([&] { readTextureSize(dir.file("wide.png")); });
    EXPECT_NE(e.find("wide.png: an image of 65000x23 pixels"), std::string::npos) << e;
    writeFileAtomic(dir.file("text.png"), "not a picture at all");
    e = test::inputErrorMessage([&] { readTextureSize(dir.file("text.png")); });
    EXPECT_NE(e.find("text.png: not a PNG or JPEG image"), std::string::npos) << e;
}

TEST(MeshIOTest, PlyVertexColoursAndTextureOption)
{
    test::TempDir dir;
    writeFileAtomic(dir.file("tri.ply"), "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                                         "property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n"
                                         "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
                                         "0 0 0 255 0 0\n1 0 0 255 0 0\n0 1 0 255 0 0\n3 0 1 2\n");
    const TriangleMesh m = readMesh(dir.file("tri.ply"));
    ASSERT_EQ(m.colours.size(), 9u);
    EXPECT_FLOAT_EQ(m.colours[0], 1.0f);
    EXPECT_FLOAT_EQ(m.colours[1], 0.0f);
    // An OBJ without .mtl takes --texture (as the Spot cow).
    writePng(dir.file("t.png"), fourTexels());
    writeFileAtomic(dir.file("bare.obj"), quadObj(""));
    MeshReadOptions o;
    o.texture = dir.file("t.png");
    EXPECT_EQ(readMesh(dir.file("bare.obj"), o).textures.size(), 1u);
    o.texture.clear();
    o.proceduralColour = true;
    const TriangleMesh p = readMesh(dir.file("bare.obj"), o);
    EXPECT_EQ(p.colours.size(), 12u);
    EXPECT_TRUE(p.textures.empty());
}

// Assimp's X3D exporter writes `<ImageTexture/>` for a material without a picture: that slot is
// no texture (it was "texture '' not found"), so --texture applies.
TEST(MeshIOTest, ATextureSlotWithoutSourceIsNoTexture)
{
    test::TempDir dir;
    writeFileAtomic(dir.file("quad.x3d"),
                    "<?xml version='1.0' encoding='UTF-8'?>\n<X3D profile='Interchange' version='3.3'><Scene><Shape>"
                    "<Appearance><ImageTexture/><Material diffuseColor='1 1 1'/></Appearance>"
                    "<IndexedFaceSet coordIndex='0 1 2 3 -1' texCoordIndex='0 1 2 3 -1'>"
                    "<Coordinate point='-1 -1 0 1 -1 0 1 1 0 -1 1 0'/><TextureCoordinate point='0 0 1 0 1 1 0 1'/>"
                    "</IndexedFaceSet></Shape></Scene></X3D>\n");
    const TriangleMesh bare = readMesh(dir.file("quad.x3d"));
    EXPECT_EQ(bare.triangleCount(), 2u);
    EXPECT_TRUE(bare.textures.empty());
    writePng(dir.file("t.png"), fourTexels());
    MeshReadOptions o;
    o.texture = dir.file("t.png");
    const TriangleMesh textured = readMesh(dir.file("quad.x3d"), o);
    ASSERT_EQ(textured.textures.size(), 1u);
    EXPECT_EQ(textured.textures[0].width, 2);
}

TEST(MeshIOTest, BadMeshesNameTheFile)
{
    test::TempDir dir;
    for (const auto& [name, named] : test::writeBadMeshes(dir)) expectErrorNaming(dir.file(name), named);
    expectErrorNaming(dir.file("nothere.obj"), "nothere.obj");
    writeFileAtomic(dir.file("junk.png"), "not an image");
    EXPECT_THROW(readTexture(dir.file("junk.png")), InputError);
}

// Assimp's OFF loader reserves what the header declares: counts the file cannot hold are refused
// first (a 57-byte file declaring 2e9 vertices took 23 GB); a folder is no mesh.
TEST(MeshIOTest, OffCountsBeyondTheFileAreRefusedBeforeAssimp)
{
    test::TempDir dir;
    writeFileAtomic(dir.file("v.off"), "OFF\n2000000000 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    writeFileAtomic(dir.file("f.off"), "OFF\n# a comment\n3 2000000000 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    for (const char* name : {"v.off", "f.off"}) {
        const std::string m = test::inputErrorMessage([&] { readMesh(dir.file(name)); });
        EXPECT_NE(m.find("more than its"), std::string::npos) << name << ": " << m;
    }
    writeFileAtomic(dir.file("ok.off"), "OFF\n# a comment\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n3 0 1 3\n");
    EXPECT_EQ(readMesh(dir.file("ok.off")).triangleCount(), 2u);
    const std::string folder = test::inputErrorMessage([&] { readMesh(dir.path().string()); });
    EXPECT_NE(folder.find("is not a regular file"), std::string::npos) << folder;
}

// Assimp 5 loops forever on a PLY header cut inside an element line and aborts the process on a
// PLY or OFF body cut short; each is refused first, naming the file. A few bytes after the last element
// (some exporters write them) and an OBJ whose last face lost a vertex still load.
TEST(MeshIOTest, CutMeshesAreRefusedAndNeitherHangNorAbort)
{
    test::TempDir dir;
    const std::string header = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
                               "property float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n";
    const std::string body = "0 0 0\n1 0 0\n0 1 0\n1 1 0\n3 0 1 2\n3 1 3 2\n";
    writeFileAtomic(dir.file("whole.ply"), header + body);
    EXPECT_EQ(readMesh(dir.file("whole.ply")).triangles.size(), 6u);
    writeFileAtomic(dir.file("trailing.ply"), header + body + "\n\n");
    EXPECT_EQ(readMesh(dir.file("trailing.ply")).triangles.size(), 6u);
    writeFileAtomic(dir.file("cuthead.ply"), header.substr(0, header.find("element vertex") + 7));
    expectErrorNaming(dir.file("cuthead.ply"), "cuthead.ply: PLY header has no 'end_header'");
    for (const std::size_t cut : {std::size_t(3), std::size_t(14), body.size() - 9}) {
        writeFileAtomic(dir.file("cutbody.ply"), header + body.substr(0, cut));
        expectErrorNaming(dir.file("cutbody.ply"), "cutbody.ply: ");
    }
    // An OFF that declares two faces and holds one: Assimp leaves the second without indices (and
    // its triangulation aborted the process on the flags left over); the primitive types now come
    // from the faces and the empty one is named.
    writeFileAtomic(dir.file("cut.off"), "OFF\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n3 0 1 2\n");
    expectErrorNaming(dir.file("cut.off"), "cut.off: mesh 0 has a face without vertices");
    writeFileAtomic(dir.file("lastface.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4\n");
    EXPECT_EQ(readMesh(dir.file("lastface.obj")).triangles.size(), 3u);
}

TEST(MeshIOTest, SpotAndBunnyLoad)
{
    SPLATWARP_REQUIRE_DATA(spot, "meshes/spot/spot_triangulated.obj");
    SPLATWARP_REQUIRE_DATA(bunny, "meshes/bunny/bun_zipper.ply");
    MeshReadOptions o;
    o.texture = test::dataPath("meshes/spot/spot_texture.png");
    const TriangleMesh s = readMesh(spot, o);
    EXPECT_EQ(s.triangleCount(), 5856u);
    EXPECT_EQ(s.textures.at(0).width, 1024);
    const TriangleMesh b = readMesh(bunny);
    EXPECT_EQ(b.triangleCount(), 69451u);
    EXPECT_TRUE(b.colours.empty());
}

} // namespace
} // namespace splatwarp
