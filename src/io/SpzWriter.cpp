/// Niantic `.spz` writer: version 3 (one gzip stream) or 4 (NGSP header + one zstd stream per
/// attribute). Quantisation as github.com/nianticlabs/spz packGaussians() (src/cc/load-spz.cc)
/// with its defaults (SH band 1 in 5 bits, bands 2-3 in 4 bits) and no coordinate conversion
/// (spz UNSPECIFIED, as our reader and splat-transform), so that its readers decode what we meant.
#include <zlib.h>
#include <zstd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <fstream>

#include "core/AtomicFile.h"
#include "core/Error.h"
#include "io/GaussianIO.h"

namespace splatwarp {

namespace {

// The attribute arrays of spz, in file order.
struct SpzArrays {
    std::string positions, alphas, colors, scales, rotations, sh;
    int fractionalBits = 12;
};

std::uint8_t toU8(float x) { return std::uint8_t(std::clamp(std::round(x), 0.0f, 255.0f)); }

// spz's quantizeSH(): 8 bits around 128, then rounded to a bucket centre (0 stays exact).
std::uint8_t quantizeSh(float x, int bucket)
{
    int q = int(std::round(x * 128.0f) + 128.0f);
    q = (q + bucket / 2) / bucket * bucket;
    return std::uint8_t(std::clamp(q, 0, 255));
}

// Niantic writes 12 fractional bits (1/4096); coordinates beyond +-2048 would wrap in 24 bits, so
// a larger model gets fewer fractional bits instead (the header carries the choice).
int fractionalBitsFor(const std::string& path, const GaussianCloud& g)
{
    double m = 0;
    for (float v : g.means) m = std::max(m, double(std::fabs(v)));
    for (int bits = 12; bits >= 0; --bits)
        if (std::round(m * std::ldexp(1.0, bits)) <= 8388607.0) return bits;
    throw InputError(msg(path, ": cannot write .spz: a centre coordinate is ", m, ", beyond the 24-bit range (+-8388607)"));
}

// spz's packQuaternionSmallestThree(): index of the largest |component| in 2 bits, the other three
// as sign + 9-bit magnitude in units of sqrt(1/2)/511, the largest made positive.
void smallestThree(const GaussianCloud& g, std::size_t i, unsigned char out[4])
{
    const Quatf r = g.rotation(i);
    float q[4] = {r.x, r.y, r.z, r.w}; // spz order x, y, z, w
    const float n = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    for (float& c : q) c /= n;
    unsigned largest = 0;
    for (unsigned k = 1; k < 4; ++k)
        if (std::fabs(q[k]) > std::fabs(q[largest])) largest = k;
    const unsigned negate = q[largest] < 0;
    std::uint32_t comp = largest;
    for (unsigned k = 0; k < 4; ++k) {
        if (k == largest) continue;
        const std::uint32_t negbit = unsigned(q[k] < 0) ^ negate;
        const auto mag = std::uint32_t(511.0f * (std::fabs(q[k]) / float(std::sqrt(0.5))) + 0.5f);
        comp = (comp << 10u) | (negbit << 9u) | mag;
    }
    for (int b = 0; b < 4; ++b) out[b] = static_cast<unsigned char>(comp >> (8 * b));
}

SpzArrays pack(const std::string& path, const GaussianCloud& g)
{
    const std::size_t n = g.size();
    const int rest = g.shCoeffs() - 1;
    SpzArrays a;
    a.fractionalBits = fractionalBitsFor(path, g);
    a.positions.resize(9 * n);
    a.alphas.resize(n);
    a.colors.resize(3 * n);
    a.scales.resize(3 * n);
    a.rotations.resize(4 * n);
    a.sh.resize(3 * std::size_t(rest) * n);
    const float scale = std::ldexp(1.0f, a.fractionalBits), colorScale = 0.15f;
    for (std::size_t i = 0; i < n; ++i) {
        const float* sh = g.shOf(i);
        for (int c = 0; c < 3; ++c) {
            const auto fixed = std::int32_t(std::round(g.means[3 * i + c] * scale));
            for (int b = 0; b < 3; ++b) a.positions[9 * i + 3 * c + b] = char((fixed >> (8 * b)) & 0xff);
            a.scales[3 * i + c] = char(toU8((g.logScales[3 * i + c] + 10.0f) * 16.0f));
            a.colors[3 * i + c] = char(toU8(sh[c] * (colorScale * 255.0f) + 0.5f * 255.0f));
            for (int j = 1; j <= rest; ++j) // coefficient-major, RGB inner, as ours
                a.sh[(i * rest + j - 1) * 3 + c] = char(quantizeSh(sh[3 * j + c], j < 4 ? 8 : 16));
        }
        a.alphas[i] = char(toU8(sigmoid(g.opacities[i]) * 255.0f));
        smallestThree(g, i, reinterpret_cast<unsigned char*>(&a.rotations[4 * i]));
    }
    return a;
}

void putU32(std::string& s, std::size_t at, std::uint64_t v)
{
    for (int b = 0; b < 4; ++b) s[at + b] = char((v >> (8 * b)) & 0xff);
}

std::string legacyHeader(const GaussianCloud& g, const SpzArrays& a, int version)
{
    std::string h(16, '\0');
    putU32(h, 0, 0x5053474e);
    putU32(h, 4, std::uint32_t(version));
    putU32(h, 8, std::uint32_t(g.size()));
    h[12] = char(g.shDegree);
    h[13] = char(a.fractionalBits);
    return h;
}

std::string gzip(const std::string& data)
{
    z_stream z{};
    if (deflateInit2(&z, Z_DEFAULT_COMPRESSION, Z_DEFLATED, 16 + MAX_WBITS, 9, Z_DEFAULT_STRATEGY) != Z_OK)
        throw IoError("cannot start deflate");
    std::string out(deflateBound(&z, uLong(data.size())) + 64, '\0');
    z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(data.data()));
    z.avail_in = uInt(data.size());
    z.next_out = reinterpret_cast<Bytef*>(&out[0]);
    z.avail_out = uInt(out.size());
    const int rc = deflate(&z, Z_FINISH);
    out.resize(z.total_out);
    deflateEnd(&z);
    if (rc != Z_STREAM_END) throw IoError("deflate failed");
    return out;
}

std::string zstd(const std::string& data)
{
    std::string out(ZSTD_compressBound(data.size()), '\0');
    const std::size_t n = ZSTD_compress(&out[0], out.size(), data.data(), data.size(), 12); // spz's level
    if (ZSTD_isError(n)) throw IoError(msg("zstd failed: ", ZSTD_getErrorName(n)));
    out.resize(n);
    return out;
}

// Version 4: 32-byte header, no extensions, TOC of (compressed, inflated) u64 pairs, the streams.
std::string ngsp(const GaussianCloud& g, const SpzArrays& a)
{
    std::vector<const std::string*> arrays = {&a.positions, &a.alphas, &a.colors, &a.scales, &a.rotations};
    if (!a.sh.empty()) arrays.push_back(&a.sh);
    std::string out = legacyHeader(g, a, 4);
    out.resize(32 + 16 * arrays.size(), '\0');
    out[15] = char(arrays.size());
    putU32(out, 16, 32);
    for (std::size_t s = 0; s < arrays.size(); ++s) {
        const std::string packed = zstd(*arrays[s]);
        putU32(out, 32 + 16 * s, packed.size()); // sizes < 4 GiB: the high words stay 0
        putU32(out, 32 + 16 * s + 8, arrays[s]->size());
        out += packed;
    }
    return out;
}

} // namespace

std::string encodeSpz(const std::string& path, const GaussianCloud& g, int version)
{
    g.checkConsistent();
    if (version != 3 && version != 4)
        throw UsageError(msg("--spz-version ", version, ": splatwarp writes .spz versions 3 and 4"));
    if (g.size() > 0x7fffffffu) throw InputError(msg(path, ": ", g.size(), " Gaussians exceed .spz's 2^31 - 1"));
    checkModelForWriting(path, g);
    const SpzArrays a = pack(path, g);
    if (version == 4) return ngsp(g, a);
    return gzip(legacyHeader(g, a, 3) + a.positions + a.alphas + a.colors + a.scales + a.rotations + a.sh);
}

void writeSpz(const std::string& path, const GaussianCloud& g, int version)
{
    writeFileAtomic(path, encodeSpz(path, g, version));
}

} // namespace splatwarp
