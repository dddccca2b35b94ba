/// glTF 2.0 binary (`.glb`) writer with KHR_gaussian_splatting: one point primitive, float32
/// attributes (POSITION, ROTATION x y z w normalised, linear SCALE, OPACITY after the sigmoid,
/// SH_DEGREE_l_COEF_n), kernel "ellipse", colorSpace "srgb_rec709_display" (3DGS trains on sRGB
/// images). No COLOR_0 fallback (optional in the extension). glTF is +Y up, +Z forward, +X left;
/// graphdeco PLY is COLMAP's x right, y down, z forward: a 180 degree turn about Z maps one to the
/// other (as splat-transform's .glb writer does), applied by the writer and undone by the reader.
#include <cmath>
#include <cstring>

#include <nlohmann/json.hpp>

#include "core/AtomicFile.h"
#include "core/Error.h"
#include "io/FormatReaders.h"

namespace splatwarp {

namespace {

using nlohmann::json;

void putLe32(std::string& s, std::uint32_t v)
{
    for (int b = 0; b < 4; ++b) s += char((v >> (8 * b)) & 0xff);
}

// Appends one float attribute (n x comps) to the BIN buffer as its own bufferView and accessor.
struct GlbBuilder {
    json doc;
    std::string bin;
    std::size_t n = 0;

    int add(const std::vector<float>& values, int comps)
    {
        static const char* const kType[] = {"", "SCALAR", "VEC2", "VEC3", "VEC4"};
        const int index = int(doc["accessors"].size());
        doc["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", bin.size()}, {"byteLength", values.size() * 4},
                                      {"target", 34962}});
        doc["accessors"].push_back({{"bufferView", index}, {"componentType", 5126}, {"count", n}, {"type", kType[comps]}});
        bin.append(reinterpret_cast<const char*>(values.data()), values.size() * 4); // little-endian host
        return index;
    }
};

std::vector<float> column(const GaussianCloud& g, int comps, float (*f)(const GaussianCloud&, std::size_t, int))
{
    std::vector<float> v(g.size() * std::size_t(comps));
    for (std::size_t i = 0; i < g.size(); ++i)
        for (int c = 0; c < comps; ++c) v[i * comps + c] = f(g, i, c);
    return v;
}

float rotationXyzw(const GaussianCloud& g, std::size_t i, int c)
{
    const Quatf q = g.rotation(i);
    const double n = std::sqrt(double(q.w) * q.w + double(q.x) * q.x + double(q.y) * q.y + double(q.z) * q.z);
    const float xyzw[4] = {q.x, q.y, q.z, q.w};
    return float(xyzw[c] / n);
}

json positionBounds(const GaussianCloud& g, const char* which)
{
    Vec3f lo, hi;
    centreBounds(g, lo, hi);
    const Vec3f& b = std::string(which) == "min" ? lo : hi;
    return json{b.x, b.y, b.z};
}

// The file before its BIN chunk's data (header, JSON chunk, BIN chunk header) and that data: a
// write streams the two, so the buffer is not copied behind a header.
struct GlbBytes {
    std::string head, bin;
};

GlbBytes container(const json& doc, std::string bin)
{
    std::string text = doc.dump();
    text.append((4 - text.size() % 4) % 4, ' ');
    bin.append((4 - bin.size() % 4) % 4, '\0');
    std::string head = "glTF";
    putLe32(head, 2);
    putLe32(head, std::uint32_t(12 + 8 + text.size() + 8 + bin.size()));
    putLe32(head, std::uint32_t(text.size()));
    putLe32(head, 0x4E4F534A);
    head += text;
    putLe32(head, std::uint32_t(bin.size()));
    putLe32(head, 0x004E4942);
    return {std::move(head), std::move(bin)};
}

// The cloud without its higher SH (those are turned as they are copied): glTF's axes for under
// a quarter of a whole copy at SH 3.
GaussianCloud turnedFrame(const GaussianCloud& ply)
{
    GaussianCloud g;
    g.means = ply.means;
    g.rotations = ply.rotations;
    g.logScales = ply.logScales;
    g.opacities = ply.opacities;
    g.sh.resize(3 * ply.size());
    for (std::size_t i = 0; i < ply.size(); ++i) std::memcpy(&g.sh[3 * i], ply.shOf(i), 3 * sizeof(float));
    turnAboutZ(g);
    return g;
}

} // namespace

void turnAboutZ(GaussianCloud& g)
{
    for (std::size_t i = 0; i < g.size(); ++i) {
        g.means[3 * i] = -g.means[3 * i];
        g.means[3 * i + 1] = -g.means[3 * i + 1];
        // (0, 0, 0, 1) * q: the quaternion of the turn applied after q.
        const Quatf q = g.rotation(i);
        g.setRotation(i, {-q.z, -q.y, q.x, q.w});
        // Each 3DGS SH basis function j is a polynomial whose degree in x, y has the parity of j, so
        // (x, y, z) -> (-x, -y, z) multiplies coefficient j by (-1)^j.
        float* sh = g.shOf(i);
        for (int j = 1; j < g.shCoeffs(); j += 2)
            for (int c = 0; c < 3; ++c) sh[3 * j + c] = -sh[3 * j + c];
    }
}

namespace {

GlbBytes glbBytes(const std::string& path, const GaussianCloud& ply)
{
    ply.checkConsistent();
    checkModelForWriting(path, ply);
    const GaussianCloud g = turnedFrame(ply);
    const std::size_t perGaussian = 4 * (3 + 4 + 3 + 1 + 3 * std::size_t(ply.shCoeffs()));
    if (g.size() > (0xffffffffu - 4096u) / perGaussian)
        throw InputError(msg(path, ": ", g.size(), " Gaussians exceed the 4 GiB a .glb can hold"));
    GlbBuilder b;
    b.n = g.size();
    b.bin.reserve(perGaussian * g.size() + 4); // grown by doubling, the old and new buffers overlapped
    b.doc = {{"asset", {{"version", "2.0"}, {"generator", "splatwarp"}}},
             {"extensionsUsed", {"KHR_gaussian_splatting"}},
             {"scene", 0}, {"scenes", {{{"nodes", {0}}}}}, {"nodes", {{{"mesh", 0}}}},
             {"accessors", json::array()}, {"bufferViews", json::array()}};
    json attrs;
    attrs["POSITION"] = b.add(g.means, 3);
    b.doc["accessors"][0]["min"] = positionBounds(g, "min");
    b.doc["accessors"][0]["max"] = positionBounds(g, "max");
    const std::string k = "KHR_gaussian_splatting:";
    attrs[k + "ROTATION"] = b.add(column(g, 4, rotationXyzw), 4);
    attrs[k + "SCALE"] = b.add(column(g, 3, [](const GaussianCloud& c, std::size_t i, int a) {
        return float(std::exp(double(c.logScales[3 * i + a])));
    }), 3);
    attrs[k + "OPACITY"] = b.add(column(g, 1, [](const GaussianCloud& c, std::size_t i, int) {
        return float(sigmoid(double(c.opacities[i])));
    }), 1);
    for (int l = 0, j = 0; l <= ply.shDegree; ++l)
        for (int m = 0; m < 2 * l + 1; ++m, ++j) {
            const float sign = j % 2 ? -1.0f : 1.0f; // turnAboutZ()'s (-1)^j
            std::vector<float> v(3 * ply.size());
            for (std::size_t i = 0; i < ply.size(); ++i)
                for (int c = 0; c < 3; ++c) v[3 * i + std::size_t(c)] = sign * ply.shOf(i)[3 * j + c];
            attrs[msg(k, "SH_DEGREE_", l, "_COEF_", m)] = b.add(v, 3);
        }
    b.doc["buffers"] = {{{"byteLength", b.bin.size()}}};
    b.doc["meshes"] = {{{"primitives", {{{"attributes", attrs}, {"mode", 0},
        {"extensions", {{"KHR_gaussian_splatting", {{"kernel", "ellipse"}, {"colorSpace", "srgb_rec709_display"},
                                                    {"projection", "perspective"}, {"sortingMethod", "cameraDistance"}}}}}}}}}};
    return container(b.doc, std::move(b.bin));
}

} // namespace

std::string encodeGlb(const std::string& path, const GaussianCloud& ply)
{
    const GlbBytes bytes = glbBytes(path, ply);
    return bytes.head + bytes.bin;
}

void writeGlb(const std::string& path, const GaussianCloud& g)
{
    const GlbBytes bytes = glbBytes(path, g);
    writeFileAtomic(path, {bytes.head, bytes.bin});
}

} // namespace splatwarp
