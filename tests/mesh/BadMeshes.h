#pragma once
/// @file BadMeshes.h
/// @brief The bad meshes of issue 31's tests (empty, no faces, a NaN vertex, a missing texture),
///        written into a folder, with the text their error must name.
#include <string>
#include <utility>
#include <vector>

#include "core/AtomicFile.h"
#include "support/TestSupport.h"

namespace splatwarp::test {

/// @brief Write the bad meshes into dir; returns (file name, text the error must contain).
inline std::vector<std::pair<std::string, std::string>> writeBadMeshes(const TempDir& dir)
{
    writeFileAtomic(dir.file("empty.obj"), "");
    writeFileAtomic(dir.file("nofaces.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\n");
    // Binary PLY: the NaN reaches the reader untouched.
    std::string ply = "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                      "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
    const float v[9] = {0, 0, 0, 1, 0, 0, 0, std::nanf(""), 0};
    ply.append(reinterpret_cast<const char*>(v), sizeof(v));
    const unsigned char n = 3;
    const int idx[3] = {0, 1, 2};
    ply.append(reinterpret_cast<const char*>(&n), 1);
    ply.append(reinterpret_cast<const char*>(idx), sizeof(idx));
    writeFileAtomic(dir.file("nan.ply"), ply);
    // A vertex colour that is NaN (binary, so the reader passes it on).
    std::string col = "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                      "property float z\nproperty float red\nproperty float green\nproperty float blue\n"
                      "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
    const float vc[18] = {0, 0, 0, 0.5f, 0.5f, 0.5f, 1, 0, 0, std::nanf(""), 0.5f, 0.5f, 0, 1, 0, 0.5f, 0.5f, 0.5f};
    col.append(reinterpret_cast<const char*>(vc), sizeof(vc));
    col.append(reinterpret_cast<const char*>(&n), 1);
    col.append(reinterpret_cast<const char*>(idx), sizeof(idx));
    writeFileAtomic(dir.file("colnan.ply"), col);
    writeFileAtomic(dir.file("q.mtl"), "newmtl m\nmap_Kd missing.png\n");
    writeFileAtomic(dir.file("notex.obj"),
                    "mtllib q.mtl\nusemtl m\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n");
    return {{"empty.obj", "empty.obj"}, {"nofaces.obj", "nofaces.obj"}, {"nan.ply", "nan.ply"}, {"notex.obj", "missing.png"},
            {"colnan.ply", "colnan.ply"}};
}

} // namespace splatwarp::test
