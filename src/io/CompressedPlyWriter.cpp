/// SuperSplat compressed PLY writer (the layout CompressedPlyReader.cpp reads), quantised as
/// splat-transform's CompressedChunk: Gaussians in Morton order of their centres, 256 a chunk;
/// per chunk float min/max of centres, log scales (clamped to +-20) and colours 0.5 + C0 f_dc;
/// centre and log scale 11-10-11 bits, rotation 2 + 3 x 10 bits (smallest three), RGBA 8 bits
/// each (A = alpha); higher SH as uchar trunc((f / 8 + 0.5) * 256).
#include <algorithm>
#include <cmath>
#include <cstring>
#include <numeric>

#include "core/AtomicFile.h"
#include "core/Error.h"
#include "io/FormatReaders.h"
#include "sh/SphericalHarmonics.h"

namespace splatwarp {

namespace {

constexpr std::size_t kChunk = 256;

std::uint32_t packUnorm(double v, int bits)
{
    const double t = double((1u << bits) - 1u);
    return std::uint32_t(std::clamp(std::floor(v * t + 0.5), 0.0, t));
}

double normalise(double x, double lo, double hi)
{
    if (x <= lo) return 0;
    if (x >= hi) return 1;
    return hi - lo < 1e-5 ? 0 : (x - lo) / (hi - lo);
}

// Spreads the low 10 bits of v to every third bit (Morton interleave).
std::uint32_t spread3(std::uint32_t v)
{
    v &= 0x3ff;
    v = (v | v << 16) & 0x30000ff;
    v = (v | v << 8) & 0x300f00f;
    v = (v | v << 4) & 0x30c30c3;
    v = (v | v << 2) & 0x9249249;
    return v;
}

std::uint32_t packRotation(const float* wxyz)
{
    double a[4], n = 0;
    for (int k = 0; k < 4; ++k) n += double(wxyz[k]) * wxyz[k];
    for (int k = 0; k < 4; ++k) a[k] = wxyz[k] / std::sqrt(n);
    int largest = 0;
    for (int k = 1; k < 4; ++k)
        if (std::fabs(a[k]) > std::fabs(a[largest])) largest = k;
    const double sign = a[largest] < 0 ? -1 : 1;
    std::uint32_t r = std::uint32_t(largest);
    for (int k = 0; k < 4; ++k)
        if (k != largest) r = (r << 10) | packUnorm(sign * a[k] * std::sqrt(0.5) + 0.5, 10);
    return r;
}

// Writes chunk c (Gaussians order[c*256 ...]) into its 18 floats and 4 uints per Gaussian.
void packChunk(const GaussianCloud& g, const std::vector<std::size_t>& order, std::size_t c, float* chunk,
               std::uint32_t* packed)
{
    const std::size_t begin = c * kChunk, end = std::min(order.size(), begin + kChunk);
    const auto colour = [&](std::size_t i, int a) { return 0.5 + kShC0 * g.shOf(i)[a]; };
    const auto value = [&](std::size_t i, int q) {
        return q < 3 ? double(g.means[3 * i + q]) : q < 6 ? double(g.logScales[3 * i + q - 3]) : colour(i, q - 6);
    };
    double lo[9], hi[9];
    for (int q = 0; q < 9; ++q) {
        lo[q] = hi[q] = value(order[begin], q);
        for (std::size_t k = begin; k < end; ++k) lo[q] = std::min(lo[q], value(order[k], q)), hi[q] = std::max(hi[q], value(order[k], q));
        if (q >= 3 && q < 6) lo[q] = std::clamp(lo[q], -20.0, 20.0), hi[q] = std::clamp(hi[q], -20.0, 20.0);
    }
    static const int kSlot[9][2] = {{0, 3}, {1, 4}, {2, 5}, {6, 9}, {7, 10}, {8, 11}, {12, 15}, {13, 16}, {14, 17}};
    for (int q = 0; q < 9; ++q) chunk[kSlot[q][0]] = float(lo[q]), chunk[kSlot[q][1]] = float(hi[q]);
    for (std::size_t k = begin; k < end; ++k) {
        const std::size_t i = order[k];
        std::uint32_t* p = packed + 4 * (k - begin);
        const auto n = [&](int q) { return normalise(value(i, q), double(float(lo[q])), double(float(hi[q]))); };
        p[0] = packUnorm(n(0), 11) << 21 | packUnorm(n(1), 10) << 11 | packUnorm(n(2), 11);
        p[1] = packRotation(&g.rotations[4 * i]);
        p[2] = packUnorm(n(3), 11) << 21 | packUnorm(n(4), 10) << 11 | packUnorm(n(5), 11);
        p[3] = packUnorm(n(6), 8) << 24 | packUnorm(n(7), 8) << 16 | packUnorm(n(8), 8) << 8 |
               packUnorm(sigmoid(double(g.opacities[i])), 8);
    }
}

std::string header(const GaussianCloud& g, std::size_t chunks)
{
    std::string h = "ply\nformat binary_little_endian 1.0\ncomment written by splatwarp\nelement chunk " +
                    std::to_string(chunks) + "\n";
    for (const char* p : {"min_x", "min_y", "min_z", "max_x", "max_y", "max_z", "min_scale_x", "min_scale_y",
                          "min_scale_z", "max_scale_x", "max_scale_y", "max_scale_z", "min_r", "min_g", "min_b",
                          "max_r", "max_g", "max_b"})
        h += std::string("property float ") + p + "\n";
    h += "element vertex " + std::to_string(g.size()) + "\n";
    for (const char* p : {"packed_position", "packed_rotation", "packed_scale", "packed_color"})
        h += std::string("property uint ") + p + "\n";
    if (g.shDegree > 0) {
        h += "element sh " + std::to_string(g.size()) + "\n";
        for (int k = 0; k < 3 * (g.shCoeffs() - 1); ++k) h += "property uchar f_rest_" + std::to_string(k) + "\n";
    }
    return h + "end_header\n";
}

} // namespace

std::vector<std::size_t> compressedPlyOrder(const GaussianCloud& g)
{
    Vec3f lo, hi;
    centreBounds(g, lo, hi);
    std::vector<std::uint32_t> code(g.size());
    for (std::size_t i = 0; i < g.size(); ++i) {
        std::uint32_t c = 0;
        for (int a = 0; a < 3; ++a) {
            const double t = normalise(g.means[3 * i + a], lo[a], hi[a]);
            c |= spread3(std::uint32_t(std::min(1023.0, t * 1024.0))) << (2 - a);
        }
        code[i] = c;
    }
    std::vector<std::size_t> order(g.size());
    std::iota(order.begin(), order.end(), std::size_t(0));
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return code[a] < code[b]; });
    return order;
}

void writeCompressedPly(const std::string& path, const GaussianCloud& g)
{
    g.checkConsistent();
    checkModelForWriting(path, g);
    const std::vector<std::size_t> order = compressedPlyOrder(g);
    const std::size_t chunks = (g.size() + kChunk - 1) / kChunk, rest = 3 * std::size_t(g.shCoeffs() - 1);
    std::vector<float> chunkData(18 * chunks);
    std::vector<std::uint32_t> packed(4 * g.size());
    for (std::size_t c = 0; c < chunks; ++c) packChunk(g, order, c, &chunkData[18 * c], &packed[4 * kChunk * c]);
    std::string sh(rest * g.size(), '\0');
    for (std::size_t k = 0; k < g.size(); ++k)
        for (int c = 0; c < 3; ++c)
            for (int j = 1; j < g.shCoeffs(); ++j) {
                const double v = g.shOf(order[k])[3 * j + c] / 8.0 + 0.5;
                sh[k * rest + std::size_t(c * (g.shCoeffs() - 1) + j - 1)] = char(std::clamp(std::trunc(v * 256), 0.0, 255.0));
            }
    std::string out = header(g, chunks); // little-endian host (see PlyWriter)
    out.append(reinterpret_cast<const char*>(chunkData.data()), chunkData.size() * 4);
    out.append(reinterpret_cast<const char*>(packed.data()), packed.size() * 4);
    writeFileAtomic(path, out + sh);
}

} // namespace splatwarp
