/// glTF 2.0 binary (`.glb`) with KHR_gaussian_splatting (Khronos, extensions/2.0/Khronos/
/// KHR_gaussian_splatting/README.md): point primitives whose attributes hold linear scales,
/// unit quaternions (x, y, z, w), opacity after the sigmoid and SH coefficients per degree and
/// order (`KHR_gaussian_splatting:SH_DEGREE_l_COEF_n`, RGB each). Only the GLB's own BIN chunk is
/// read (no external or data: URIs). Node transforms are applied (GltfNodes.cpp), then glTF's axes
/// are turned into graphdeco's (turnAboutZ(), GltfWriter.cpp).
#include <cmath>
#include <cstring>
#include <limits>
#include <string_view>

#include <nlohmann/json.hpp>

#include "core/Error.h"
#include "io/FormatReaders.h"
#include "io/GltfNodes.h"
#include "io/JsonText.h"

namespace splatwarp {

namespace {

using nlohmann::json;

constexpr std::uint32_t kChunkJson = 0x4E4F534A, kChunkBin = 0x004E4942;
const std::string kPrefix = "KHR_gaussian_splatting:";

std::uint32_t le32(const std::string& d, std::size_t at)
{
    const auto* p = reinterpret_cast<const unsigned char*>(d.data()) + at;
    return std::uint32_t(p[0]) | std::uint32_t(p[1]) << 8 | std::uint32_t(p[2]) << 16 | std::uint32_t(p[3]) << 24;
}

// One accessor resolved to bytes inside the BIN chunk (bounds checked).
struct View {
    const unsigned char* base = nullptr;
    std::size_t stride = 0, count = 0;
    int type = 0, comps = 0;
    bool normalized = false;
};

int componentBytes(int type)
{
    switch (type) {
    case 5120: case 5121: return 1;
    case 5122: case 5123: return 2;
    case 5125: case 5126: return 4;
    default: return 0;
    }
}

double component(const View& v, std::size_t i, int c)
{
    const unsigned char* p = v.base + i * v.stride + std::size_t(c) * componentBytes(v.type);
    switch (v.type) {
    case 5120: { std::int8_t x; std::memcpy(&x, p, 1); return v.normalized ? std::max(x / 127.0, -1.0) : x; }
    case 5121: return v.normalized ? p[0] / 255.0 : p[0];
    case 5122: { std::int16_t x; std::memcpy(&x, p, 2); return v.normalized ? std::max(x / 32767.0, -1.0) : x; }
    case 5123: { std::uint16_t x; std::memcpy(&x, p, 2); return v.normalized ? x / 65535.0 : x; }
    case 5125: { std::uint32_t x; std::memcpy(&x, p, 4); return x; }
    default: { float x; std::memcpy(&x, p, 4); return x; }
    }
}

struct Glb {
    std::string path;
    json doc;
    std::string_view bin; ///< into the file's bytes, which outlive it (a copy was the file's size again)
};

Glb parseContainer(const std::string& path, const std::string& data, ReadReport& report)
{
    if (data.size() < 20) throw InputError(msg(path, ": .glb truncated: ", data.size(), " bytes, less than a header and a chunk"));
    if (le32(data, 4) != 2) throw InputError(msg(path, ": .glb version ", le32(data, 4), " is not supported (2 is)"));
    const std::size_t length = le32(data, 8);
    if (length > data.size()) throw InputError(msg(path, ": .glb truncated: header says ", length, " bytes, the file has ", data.size()));
    if (length < data.size()) report.notes.push_back("data after the .glb's declared length ignored");
    Glb g{path, {}, {}};
    std::size_t at = 12;
    bool haveJson = false;
    while (at + 8 <= length) {
        const std::size_t size = le32(data, at), type = le32(data, at + 4);
        if (size > length - at - 8) throw InputError(msg(path, ": .glb truncated: chunk at byte ", at, " of ", size, " bytes"));
        if (type == kChunkJson && !haveJson) {
            try {
                g.doc = parseJson(data.begin() + long(at + 8), data.begin() + long(at + 8 + size));
            } catch (const json::exception& e) {
                throw InputError(msg(path, ": .glb JSON chunk: ", e.what()));
            }
            haveJson = true;
        } else if (type == kChunkBin && g.bin.empty()) {
            g.bin = std::string_view(data).substr(at + 8, size);
        }
        at += 8 + size;
    }
    if (!haveJson || !g.doc.is_object()) throw InputError(msg(path, ": .glb without a JSON object chunk"));
    return g;
}

const json& member(const Glb& g, const json& parent, const char* key, std::size_t index)
{
    if (!parent.contains(key) || !parent[key].is_array() || index >= parent[key].size())
        throw InputError(msg(g.path, ": .glb: ", key, "[", index, "] does not exist"));
    return parent[key][index];
}

std::size_t count(const Glb& g, const json& o, const char* key, std::size_t otherwise)
{
    if (!o.contains(key)) return otherwise;
    if (!o[key].is_number_unsigned()) throw InputError(msg(g.path, ": .glb: '", key, "' is not a non-negative integer"));
    return o[key].get<std::size_t>();
}

View accessorView(const Glb& g, std::size_t index, const std::string& name)
{
    const json& a = member(g, g.doc, "accessors", index);
    if (a.contains("sparse")) throw InputError(msg(g.path, ": .glb: sparse accessor for ", name, " is not supported"));
    if (!a.contains("bufferView")) throw InputError(msg(g.path, ": .glb: accessor for ", name, " has no bufferView"));
    static const std::pair<const char*, int> kTypes[] = {{"SCALAR", 1}, {"VEC2", 2}, {"VEC3", 3}, {"VEC4", 4}};
    View v;
    v.type = int(count(g, a, "componentType", 0));
    v.count = count(g, a, "count", 0);
    v.normalized = a.value("normalized", false);
    for (const auto& [t, n] : kTypes)
        if (a.value("type", std::string()) == t) v.comps = n;
    const int cb = componentBytes(v.type);
    if (cb == 0 || v.comps == 0) throw InputError(msg(g.path, ": .glb: accessor for ", name, " has an unknown type"));
    const json& bv = member(g, g.doc, "bufferViews", count(g, a, "bufferView", 0));
    const json& buffer = member(g, g.doc, "buffers", count(g, bv, "buffer", 0));
    if (count(g, bv, "buffer", 0) != 0 || buffer.contains("uri"))
        throw InputError(msg(g.path, ": .glb: ", name, " is in an external buffer (only the GLB's BIN chunk is read)"));
    const std::size_t elem = std::size_t(cb) * std::size_t(v.comps);
    const std::uint64_t viewOffset = count(g, bv, "byteOffset", 0), viewLength = count(g, bv, "byteLength", 0);
    const std::uint64_t offset = count(g, a, "byteOffset", 0);
    v.stride = count(g, bv, "byteStride", elem);
    if (v.stride < elem || viewOffset > g.bin.size() || viewLength > g.bin.size() - viewOffset ||
        (v.count > 0 && (offset > viewLength || viewLength - offset < elem ||
                         (viewLength - offset - elem) / v.stride < v.count - 1)))
        throw InputError(msg(g.path, ": .glb: ", name, " (", v.count, " elements) does not fit in its buffer view"));
    v.base = reinterpret_cast<const unsigned char*>(g.bin.data()) + viewOffset + offset;
    return v;
}

// The highest SH degree whose coefficients (and those of every lower degree) are all present.
int shDegreeOf(const Glb& g, const json& attributes)
{
    int degree = 0;
    for (int l = 1; l <= 3; ++l) {
        int present = 0;
        for (int n = 0; n < 2 * l + 1; ++n)
            present += attributes.contains(msg(kPrefix, "SH_DEGREE_", l, "_COEF_", n));
        if (present == 0) break;
        if (present != 2 * l + 1)
            throw InputError(msg(g.path, ": .glb: SH degree ", l, " is partially defined (", present, " of ", 2 * l + 1,
                                 " coefficients)"));
        degree = l;
    }
    return degree;
}

View attribute(const Glb& g, const json& attributes, const std::string& name, int comps, std::size_t n)
{
    if (!attributes.contains(name)) throw InputError(msg(g.path, ": .glb: splat primitive without ", name));
    const View v = accessorView(g, count(g, attributes, name.c_str(), 0), name);
    if (v.comps != comps) throw InputError(msg(g.path, ": .glb: ", name, " has ", v.comps, " components, ", comps, " expected"));
    if (v.count != n) throw InputError(msg(g.path, ": .glb: ", name, " holds ", v.count, " values, POSITION ", n));
    return v;
}

// logit of an opacity in [0, 1]; 0 and 1 move to the nearest float inside (the logit stays finite).
float opacityLogit(const std::string& path, std::size_t i, double a)
{
    if (std::isnan(a)) return float(a);
    if (a < 0 || a > 1) throw InputError(msg(path, ": Gaussian ", i, ": opacity ", a, " is outside [0, 1]"));
    a = std::min(std::max(a, double(std::numeric_limits<float>::min())), 1.0 - std::ldexp(1.0, -24));
    return float(std::log(a / (1 - a)));
}

GaussianCloud readPrimitive(const Glb& g, const json& prim, ReadReport& report)
{
    const json& ext = prim["extensions"]["KHR_gaussian_splatting"];
    const json& attrs = prim.value("attributes", json::object());
    if (ext.value("kernel", std::string("ellipse")) != "ellipse")
        throw InputError(msg(g.path, ": .glb: kernel '", printable(ext.value("kernel", std::string())), "' is not supported (ellipse is)"));
    const std::string space = ext.value("colorSpace", std::string());
    if (space != "srgb_rec709_display")
        report.notes.push_back(msg("colorSpace '", printable(space), "' read as given (splatwarp renders as srgb_rec709_display)"));
    if (prim.value("mode", 4) != 0) report.notes.push_back("splat primitive whose mode is not POINTS read as points");
    const View pos = accessorView(g, count(g, attrs, "POSITION", 0), "POSITION");
    const std::size_t n = pos.count;
    const View rot = attribute(g, attrs, kPrefix + "ROTATION", 4, n), scale = attribute(g, attrs, kPrefix + "SCALE", 3, n);
    const View alpha = attribute(g, attrs, kPrefix + "OPACITY", 1, n);
    const int degree = shDegreeOf(g, attrs);
    std::vector<View> sh = {attribute(g, attrs, kPrefix + "SH_DEGREE_0_COEF_0", 3, n)};
    for (int l = 1; l <= degree; ++l)
        for (int m = 0; m < 2 * l + 1; ++m) sh.push_back(attribute(g, attrs, msg(kPrefix, "SH_DEGREE_", l, "_COEF_", m), 3, n));
    if (pos.comps != 3) throw InputError(msg(g.path, ": .glb: POSITION has ", pos.comps, " components"));
    GaussianCloud p;
    p.resize(n, degree);
    for (std::size_t i = 0; i < n; ++i) {
        for (int a = 0; a < 3; ++a) {
            p.means[3 * i + a] = float(component(pos, i, a));
            p.logScales[3 * i + a] = float(std::log(component(scale, i, a)));
        }
        p.setRotation(i, {float(component(rot, i, 3)), float(component(rot, i, 0)), float(component(rot, i, 1)),
                          float(component(rot, i, 2))});
        p.opacities[i] = opacityLogit(g.path, i, component(alpha, i, 0));
        for (std::size_t j = 0; j < sh.size(); ++j)
            for (int c = 0; c < 3; ++c) p.shOf(i)[3 * j + c] = float(component(sh[j], i, c));
    }
    return p;
}

// Appends `part`; primitives of different SH degrees meet at the lower one.
void appendCloud(GaussianCloud& out, GaussianCloud part, ReadReport& report)
{
    if (out.empty()) {
        out = std::move(part);
        return;
    }
    const int d = std::min(out.shDegree, part.shDegree);
    if (d != out.shDegree || d != part.shDegree)
        report.notes.push_back(msg("splat primitives of several SH degrees read at degree ", d));
    out = withShDegree(out, d);
    const GaussianCloud q = withShDegree(part, d);
    for (std::size_t i = 0; i < q.size(); ++i) out.append(q, i);
}

bool isSplatPrimitive(const json& prim)
{
    return prim.is_object() && prim.contains("extensions") && prim["extensions"].is_object() &&
           prim["extensions"].contains("KHR_gaussian_splatting") && prim["extensions"]["KHR_gaussian_splatting"].is_object();
}

// The splat primitives of one mesh, concatenated; returns how many there were.
std::size_t readMesh(const Glb& g, std::size_t index, GaussianCloud& out, ReadReport& report)
{
    const json& mesh = member(g, g.doc, "meshes", index);
    if (!mesh.is_object() || !mesh.contains("primitives") || !mesh["primitives"].is_array()) return 0;
    std::size_t primitives = 0;
    for (const json& prim : mesh["primitives"]) {
        if (!isSplatPrimitive(prim)) continue;
        if (!prim.value("attributes", json()).is_object())
            throw InputError(msg(g.path, ": .glb: splat primitive without attributes"));
        appendCloud(out, readPrimitive(g, prim, report), report);
        ++primitives;
    }
    return primitives;
}

bool isIdentity(const NodeTransform& t)
{
    const Mat3d one = Mat3d::identity();
    for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b)
            if (t.m[a][b] != one[a][b]) return false;
    return t.t[0] == 0 && t.t[1] == 0 && t.t[2] == 0;
}

// Every mesh a node of the scene places, moved by the node's transform (each placement is a copy);
// a file without nodes: every mesh in its own space.
GaussianCloud readGlbDocument(const std::string& path, const std::string& data, ReadReport& report)
{
    const Glb g = parseContainer(path, data, report);
    std::vector<MeshInstance> instances = meshInstances(path, g.doc);
    if (instances.empty() && g.doc.contains("meshes") && g.doc["meshes"].is_array())
        for (std::size_t m = 0; m < g.doc["meshes"].size(); ++m) instances.push_back({m, NodeTransform{}});
    GaussianCloud out;
    std::size_t primitives = 0;
    for (const MeshInstance& inst : instances) {
        GaussianCloud part;
        const std::size_t n = readMesh(g, inst.mesh, part, report);
        if (n == 0) continue;
        primitives += n;
        if (!isIdentity(inst.transform)) applyNodeTransform(path, inst.transform, part);
        appendCloud(out, std::move(part), report);
    }
    if (primitives == 0) throw InputError(msg(path, ": .glb without KHR_gaussian_splatting primitives"));
    turnAboutZ(out);
    report.format = "glb";
    return out;
}

} // namespace

bool hasGlbMagic(const std::string& data) { return data.compare(0, 4, "glTF") == 0; }

GaussianCloud readGlb(const std::string& path, const std::string& data, ReadReport& report)
{
    try {
        return readGlbDocument(path, data, report);
    } catch (const nlohmann::json::exception& e) { // a member of the wrong JSON type
        throw InputError(msg(path, ": .glb JSON: ", e.what()));
    }
}


} // namespace splatwarp
