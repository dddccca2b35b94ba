/// SuperSplat compressed PLY reader. Layout (PlayCanvas SuperSplat / splat-transform):
/// `chunk` element, one record per 256 Gaussians, with float min/max of position, log-scale and
/// (optionally) colour; `vertex` element of four uint32:
///   packed_position, packed_scale: 11-10-11 bit unorm (x in the top bits) lerped in chunk min/max;
///   packed_rotation: top 2 bits = index of the largest component (dropped, recovered from unit
///                    norm), then three 10-bit values of the others in order, each in
///                    [-1/sqrt2, 1/sqrt2];
///   packed_color:    8-8-8-8 RGBA (R in the top byte); RGB lerped in chunk min/max when present,
///                    A is alpha.
/// Optional `sh` element: uchar f_rest_* (same channel-major order as graphdeco), value
/// 8 * (n - 0.5) with n = 0, 1 for the end codes and (q + 0.5) / 256 otherwise.
#include <cmath>

#include "core/Error.h"
#include "io/FormatReaders.h"
#include "sh/SphericalHarmonics.h"

namespace splatwarp {

namespace {

constexpr std::size_t kChunkSize = 256; // Gaussians per chunk record

const char* const kChunkProps[] = {"min_x", "min_y", "min_z", "max_x", "max_y", "max_z",
                                   "min_scale_x", "min_scale_y", "min_scale_z",
                                   "max_scale_x", "max_scale_y", "max_scale_z"};
const char* const kColourProps[] = {"min_r", "min_g", "min_b", "max_r", "max_g", "max_b"};
const char* const kPackedProps[] = {"packed_position", "packed_rotation", "packed_scale", "packed_color"};

double unorm(std::uint32_t v, int bits)
{
    const std::uint32_t mask = (1u << bits) - 1u;
    return double(v & mask) / double(mask);
}

double lerp(double a, double b, double t) { return a * (1.0 - t) + b * t; }

// 11-10-11 bits, x in the top 11.
void unpack111011(std::uint32_t v, double out[3])
{
    out[0] = unorm(v >> 21, 11);
    out[1] = unorm(v >> 11, 10);
    out[2] = unorm(v, 11);
}

// "Smallest three": the three stored components lie in [-1/sqrt2, 1/sqrt2].
void unpackRotation(std::uint32_t v, float q[4])
{
    const double range = std::sqrt(2.0);
    const double abc[3] = {(unorm(v >> 20, 10) - 0.5) * range, (unorm(v >> 10, 10) - 0.5) * range,
                           (unorm(v, 10) - 0.5) * range};
    const double largest = std::sqrt(std::max(0.0, 1.0 - (abc[0] * abc[0] + abc[1] * abc[1] + abc[2] * abc[2])));
    const unsigned which = v >> 30;
    for (unsigned a = 0, j = 0; a < 4; ++a) q[a] = float(a == which ? largest : abc[j++]);
}

std::vector<int> columns(const std::string& path, const PlyElement& e, const std::vector<std::string>& names)
{
    std::vector<int> col;
    for (const std::string& n : names) {
        col.push_back(e.find(n));
        if (col.back() < 0) throw InputError(msg(path, ": compressed PLY element '", e.name, "' lacks property '", n, "'"));
    }
    return col;
}

/// Column indices of the chunk and vertex properties, checked against the vertex count.
struct CompressedLayout {
    std::vector<int> chunk;  ///< kChunkProps
    std::vector<int> colour; ///< kColourProps; empty when the chunks have no colour range
    std::vector<int> packed; ///< kPackedProps
};

CompressedLayout compressedLayout(const std::string& path, const PlyElementValues& chunk,
                                  const PlyElementValues& vertex)
{
    const std::size_t n = vertex.count();
    if (chunk.count() != (n + kChunkSize - 1) / kChunkSize)
        throw InputError(msg(path, ": compressed PLY has ", chunk.count(), " chunk records for ", n,
                             " vertices; expected ", (n + kChunkSize - 1) / kChunkSize, " (", kChunkSize,
                             " per chunk)"));
    CompressedLayout l;
    l.chunk = columns(path, chunk.element(), {std::begin(kChunkProps), std::end(kChunkProps)});
    if (chunk.element().find("min_r") >= 0)
        l.colour = columns(path, chunk.element(), {std::begin(kColourProps), std::end(kColourProps)});
    l.packed = columns(path, vertex.element(), {std::begin(kPackedProps), std::end(kPackedProps)});
    for (int c : l.packed)
        if (vertex.element().properties[c].type != PlyType::UInt32)
            throw InputError(msg(path, ": compressed PLY property '", vertex.element().properties[c].name,
                                 "' must be uint"));
    return l;
}

/// The optional `sh` element: higher SH bands (degree 0 and no values when absent).
struct CompressedSh {
    int degree = 0;
    const PlyElementValues* values = nullptr;
    std::vector<int> columns; ///< f_rest_0 ...
};

CompressedSh compressedSh(const std::string& path, const PlyHeader& header, const PlyBody& body, std::size_t n)
{
    CompressedSh out;
    if (!header.find("sh")) return out;
    out.values = &body.element("sh");
    const std::size_t m = out.values->element().properties.size();
    for (int d = 1; d <= 3; ++d)
        if (m == std::size_t(3 * (shCoeffCount(d) - 1))) out.degree = d;
    if (out.degree == 0)
        throw InputError(msg(path, ": compressed PLY element 'sh' has ", m, " properties; expected 9, 24 or 45"));
    if (out.values->count() != n)
        throw InputError(msg(path, ": compressed PLY element 'sh' has ", out.values->count(), " records for ", n,
                             " vertices"));
    std::vector<std::string> names;
    for (std::size_t j = 0; j < m; ++j) names.push_back("f_rest_" + std::to_string(j));
    out.columns = columns(path, out.values->element(), names);
    return out;
}

/// Decode vertex i into Gaussian i of g.
void decodeVertex(std::size_t i, const PlyElementValues& chunk, const PlyElementValues& vertex,
                  const CompressedLayout& l, const CompressedSh& sh, GaussianCloud& g)
{
    const std::size_t ci = i / kChunkSize;
    const auto packed = [&](int j) { return std::uint32_t(vertex.get(i, l.packed[j])); };
    const auto ch = [&](int j) { return chunk.get(ci, l.chunk[j]); };
    double t[3];
    unpack111011(packed(0), t);
    for (int a = 0; a < 3; ++a) g.means[3 * i + a] = float(lerp(ch(a), ch(3 + a), t[a]));
    unpackRotation(packed(1), &g.rotations[4 * i]);
    unpack111011(packed(2), t);
    for (int a = 0; a < 3; ++a) g.logScales[3 * i + a] = float(lerp(ch(6 + a), ch(9 + a), t[a]));
    const std::uint32_t rgba = packed(3);
    float* s = g.shOf(i);
    for (int a = 0; a < 3; ++a) {
        double c = unorm(rgba >> (24 - 8 * a), 8);
        if (!l.colour.empty()) c = lerp(chunk.get(ci, l.colour[a]), chunk.get(ci, l.colour[3 + a]), c);
        s[a] = float((c - 0.5) / kShC0);
    }
    g.opacities[i] = logitOfU8Alpha(rgba & 0xffu);
    const int k = g.shCoeffs();
    for (int c = 0; c < 3 && sh.values; ++c)
        for (int j = 1; j < k; ++j) {
            const double q = sh.values->get(i, sh.columns[std::size_t(c * (k - 1) + j - 1)]);
            const double u = q == 0 ? 0.0 : q == 255 ? 1.0 : (q + 0.5) / 256.0;
            s[3 * j + c] = float((u - 0.5) * 8.0);
        }
}

} // namespace

bool isCompressedPly(const PlyHeader& header)
{
    const PlyElement* vertex = header.find("vertex");
    return header.find("chunk") && vertex && vertex->find("packed_position") >= 0;
}

GaussianCloud readCompressedPly(const std::string& path, const PlyHeader& header, const PlyBody& body,
                                ReadReport& report)
{
    const PlyElementValues& chunk = body.element("chunk");
    const PlyElementValues& vertex = body.element("vertex");
    const std::size_t n = vertex.count();
    const CompressedLayout layout = compressedLayout(path, chunk, vertex);
    const CompressedSh sh = compressedSh(path, header, body, n);
    for (const std::string& note : skippedElementNotes(header, {"chunk", "vertex", "sh"})) report.notes.push_back(note);

    GaussianCloud g;
    g.resize(n, sh.degree);
    for (std::size_t i = 0; i < n; ++i) decodeVertex(i, chunk, vertex, layout, sh, g);
    report.format = "ply-compressed";
    return g;
}

} // namespace splatwarp
