#include "mesh/MeshIO.h"

#include <assimp/DefaultIOSystem.h>
#include <assimp/Importer.hpp>
#include <assimp/material.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "core/AtomicFile.h"
#include "core/Error.h"
#include "image/ImageIO.h"
#include "image/TextureIO.h"
#include "io/PlyBody.h"
#include "io/PlyHeader.h"

namespace splatwarp {

namespace {

namespace fs = std::filesystem;

/// Texture of a material: an embedded one ("*0" or a name the scene resolves) or a file beside
/// the mesh. Returns an index into mesh.textures, loading each distinct source once.
int loadTexture(const aiScene& scene, const std::string& ref, const std::string& meshPath, TriangleMesh& mesh,
                std::map<std::string, int>& loaded)
{
    const auto it = loaded.find(ref);
    if (it != loaded.end()) return it->second;
    Image image;
    if (const aiTexture* t = scene.GetEmbeddedTexture(ref.c_str())) {
        if (t->mHeight != 0) { // raw texels, BGRA
            checkImageSize(msg(meshPath, ": embedded texture ", ref), t->mWidth, t->mHeight);
            image = Image(int(t->mWidth), int(t->mHeight), 4);
            for (std::size_t i = 0; i < std::size_t(t->mWidth) * t->mHeight; ++i) {
                const aiTexel& p = t->pcData[i];
                const float v[4] = {p.r / 255.0f, p.g / 255.0f, p.b / 255.0f, p.a / 255.0f};
                for (int c = 0; c < 4; ++c) image.pixels[4 * i + std::size_t(c)] = v[c];
            }
        } else {
            image = decodeTexture(reinterpret_cast<const unsigned char*>(t->pcData), t->mWidth,
                                  msg(meshPath, ": embedded texture ", ref));
        }
    } else {
        const fs::path file = fs::path(ref).is_absolute() ? fs::path(ref) : fs::path(meshPath).parent_path() / ref;
        if (!fs::is_regular_file(file)) throw InputError(msg(meshPath, ": texture '", ref, "' not found (", file.string(), ")"));
        image = readTexture(file.string());
    }
    mesh.textures.push_back(std::move(image));
    loaded[ref] = int(mesh.textures.size() - 1);
    return loaded[ref];
}

/// A material's base colour or diffuse texture; empty when it has none. An exporter may write a
/// texture slot without a source (Assimp's X3D: `<ImageTexture/>`): that is no texture either.
std::string materialTexture(const aiMaterial& mat)
{
    for (const aiTextureType type : {aiTextureType_BASE_COLOR, aiTextureType_DIFFUSE}) {
        aiString tex;
        if (mat.GetTexture(type, 0, &tex) == AI_SUCCESS && tex.length > 0) return tex.C_Str();
    }
    return {};
}

std::vector<MeshMaterial> readMaterials(const aiScene& scene, const std::string& path, const MeshReadOptions& o,
                                        TriangleMesh& mesh)
{
    std::map<std::string, int> loaded;
    std::vector<MeshMaterial> out;
    for (unsigned m = 0; m < scene.mNumMaterials; ++m) {
        const aiMaterial& mat = *scene.mMaterials[m];
        MeshMaterial mm;
        aiColor4D c;
        aiString name;
        mat.Get(AI_MATKEY_NAME, name);
        // assimp's stand-in for "no material" is grey: show the mesh white instead.
        if (std::string(name.C_Str()) != AI_DEFAULT_MATERIAL_NAME &&
            (mat.Get(AI_MATKEY_BASE_COLOR, c) == AI_SUCCESS || mat.Get(AI_MATKEY_COLOR_DIFFUSE, c) == AI_SUCCESS))
            mm.colour = Vec3f(c.r, c.g, c.b);
        const std::string tex = materialTexture(mat);
        if (!tex.empty())
            mm.texture = loadTexture(scene, tex, path, mesh, loaded);
        else if (!o.texture.empty())
            mm.texture = loadTexture(scene, fs::absolute(o.texture).string(), path, mesh, loaded);
        out.push_back(mm);
    }
    if (out.empty()) out.push_back(MeshMaterial());
    return out;
}

void appendMesh(const aiMesh& m, TriangleMesh& mesh, bool& anyUv, bool& anyColour)
{
    const std::uint32_t base = std::uint32_t(mesh.vertexCount());
    for (unsigned i = 0; i < m.mNumVertices; ++i) {
        const aiVector3D& p = m.mVertices[i];
        mesh.positions.insert(mesh.positions.end(), {p.x, p.y, p.z});
        const aiVector3D uv = m.HasTextureCoords(0) ? m.mTextureCoords[0][i] : aiVector3D(0, 0, 0);
        mesh.uvs.insert(mesh.uvs.end(), {uv.x, uv.y});
        const aiColor4D col = m.HasVertexColors(0) ? m.mColors[0][i] : aiColor4D(1, 1, 1, 1);
        mesh.colours.insert(mesh.colours.end(), {col.r, col.g, col.b});
    }
    anyUv = anyUv || m.HasTextureCoords(0);
    anyColour = anyColour || m.HasVertexColors(0);
    for (unsigned f = 0; f < m.mNumFaces; ++f) {
        const aiFace& face = m.mFaces[f];
        if (face.mNumIndices != 3) continue; // points and lines left by the importer
        for (int k = 0; k < 3; ++k) mesh.triangles.push_back(base + face.mIndices[k]);
        mesh.materialOf.push_back(m.mMaterialIndex);
    }
}

/// A PLY mesh's header and body walked by our own (fuzzed) PLY parser before Assimp reads it:
/// Assimp 5's PLY loader loops forever on a header cut inside an `element` line, and aborts the
/// process (an assertion in its triangulation) on a body cut inside the vertices or faces.
void checkPlyMesh(const std::string& path)
{
    char magic[3] = {};
    if (!std::ifstream(path, std::ios::binary).read(magic, 3) || std::string(magic, 3) != "ply") return; // Assimp's checks
    const std::string data = readWholeFile(path);
    PlyBody(path, data, parsePlyHeader(path, data), PlyBody::Trailing::Allow);
}

/// An OFF header's counts against the file's size before Assimp reads it: its loader reserves
/// what the header declares (a 57-byte file declaring 2e9 vertices took 23 GB). A vertex takes
/// at least 6 bytes ("0 0 0\n"), a face 8 ("3 0 1 2\n").
void checkOffCounts(const std::string& path)
{
    std::ifstream in(path, std::ios::binary);
    std::string head(4096, '\0');
    in.read(&head[0], std::streamsize(head.size()));
    head.resize(std::size_t(in.gcount()));
    std::istringstream words(head);
    std::string word;
    if (!(words >> word) || word.size() < 3 || word.compare(word.size() - 3, 3, "OFF") != 0) return; // not OFF
    std::vector<double> counts;
    while (counts.size() < 2 && words >> word) {
        if (word[0] == '#') {
            std::getline(words, word);
            continue;
        }
        char* end = nullptr;
        const double v = std::strtod(word.c_str(), &end);
        if (*end != '\0') return; // not the counts: Assimp's own checks
        counts.push_back(v);
    }
    std::error_code ec;
    const double size = double(fs::file_size(path, ec));
    if (counts.size() == 2 && (counts[0] > size / 6 || counts[1] > size / 8))
        throw InputError(msg(path, ": its OFF header declares ", counts[0], " vertices and ", counts[1], " faces, more than its ",
                             size, " bytes can hold (a cut or corrupt file?)"));
}

/// Each mesh's primitive types taken from its faces, as Assimp's triangulation asserts they are
/// (a loader that leaves a polygon flag on a mesh of triangles or of no faces aborts the process
/// there); a face without indices is refused.
void setPrimitiveTypes(const aiScene& scene, const std::string& path)
{
    for (unsigned i = 0; i < scene.mNumMeshes; ++i) {
        aiMesh& m = *scene.mMeshes[i];
        unsigned types = 0;
        for (unsigned f = 0; f < m.mNumFaces; ++f) {
            const unsigned n = m.mFaces[f].mNumIndices;
            if (n == 0) throw InputError(msg(path, ": mesh ", i, " has a face without vertices (a cut or corrupt file?)"));
            types |= n == 1 ? aiPrimitiveType_POINT : n == 2 ? aiPrimitiveType_LINE : n == 3 ? aiPrimitiveType_TRIANGLE
                                                                                            : aiPrimitiveType_POLYGON;
        }
        m.mPrimitiveTypes = types;
    }
}

/// Assimp's file access: every file it opens (the mesh, an .mtl, a glTF's buffers) is an input of
/// the command, so that no output of it may replace that file.
class InputRecordingIO : public Assimp::DefaultIOSystem {
public:
    Assimp::IOStream* Open(const char* file, const char* mode) override
    {
        if (OutputSet* outputs = OutputSet::active()) outputs->addInput(file);
        return DefaultIOSystem::Open(file, mode);
    }
};

} // namespace

TriangleMesh readMesh(const std::string& path, const MeshReadOptions& o)
{
    std::error_code ec;
    if (!fs::exists(path, ec)) throw InputError(msg(path, ": mesh file not found"));
    if (!fs::is_regular_file(path, ec)) throw InputError(msg(path, ": is not a regular file (a folder, device or FIFO), not a mesh"));
    checkPlyMesh(path);
    checkOffCounts(path);
    Assimp::Importer importer;
    importer.SetIOHandler(new InputRecordingIO); // the importer owns it
    importer.SetPropertyInteger(AI_CONFIG_PP_SBP_REMOVE, aiPrimitiveType_POINT | aiPrimitiveType_LINE);
    // Read, then validated and post-processed once the primitive types are the faces' own.
    const aiScene* scene = importer.ReadFile(path, 0);
    if (!scene || !scene->mRootNode) throw InputError(msg(path, ": cannot read mesh: ", importer.GetErrorString()));
    setPrimitiveTypes(*scene, path);
    scene = importer.ApplyPostProcessing(aiProcess_ValidateDataStructure | aiProcess_Triangulate | aiProcess_PreTransformVertices |
                                         aiProcess_SortByPType);
    if (!scene || !scene->mRootNode) throw InputError(msg(path, ": cannot read mesh: ", importer.GetErrorString()));
    TriangleMesh mesh;
    mesh.name = path;
    mesh.materials = readMaterials(*scene, path, o, mesh);
    bool anyUv = false, anyColour = false;
    for (unsigned i = 0; i < scene->mNumMeshes; ++i) appendMesh(*scene->mMeshes[i], mesh, anyUv, anyColour);
    if (!anyUv) {
        for (const MeshMaterial& m : mesh.materials)
            if (m.texture >= 0) throw InputError(msg(path, ": a texture but no texture coordinates in the mesh"));
        mesh.uvs.clear();
    }
    if (!anyColour) mesh.colours.clear();
    if (o.proceduralColour && mesh.vertexCount() > 0) applyProceduralColour(mesh);
    mesh.checkValid();
    return mesh;
}

} // namespace splatwarp
