/// Niantic `.spz` reader (versions 2 and 3): a gzip stream holding a 16-byte header and the
/// Gaussians attribute by attribute (positions, alphas, colours, scales, rotations, SH).
/// Layout and decoding follow github.com/nianticlabs/spz (README, src/cc/load-spz.cc). Values are
/// read without a coordinate conversion, as splat-transform and spz's UNSPECIFIED default do.
#include <zlib.h>

#include <cmath>
#include <cstdint>
#include <cstring>

#include "core/Error.h"
#include "io/FormatReaders.h"

namespace splatwarp {

namespace {

constexpr std::uint32_t kSpzMagic = 0x5053474e; // "NGSP" little-endian
constexpr std::size_t kSpzHeaderBytes = 16;
constexpr std::uint8_t kSpzFlagExtensions = 0x2;
// spz colours are f_dc scaled by 0.15 (not kShC0) so that out-of-gamut DC terms survive.
constexpr double kSpzColorScale = 0.15;
// Deflate cannot expand more than 1032:1 (RFC 1951 block limits, zlib's technical FAQ); a header
// claiming more than that many bytes of Gaussians lies, and is refused before any allocation.
constexpr double kMaxDeflateRatio = 1032.0;

struct SpzHeader {
    std::uint32_t magic = 0, version = 0, count = 0;
    int shDegree = 0, fractionalBits = 0, flags = 0;
};

std::uint32_t u32le(const unsigned char* p)
{
    return std::uint32_t(p[0]) | std::uint32_t(p[1]) << 8 | std::uint32_t(p[2]) << 16 | std::uint32_t(p[3]) << 24;
}

int shRestCoeffs(int degree) { return (degree + 1) * (degree + 1) - 1; }

// Bytes of one Gaussian: position 3x24 bit, alpha, RGB, 3 log scales, rotation, SH bytes.
std::size_t bytesPerGaussian(const SpzHeader& h)
{
    return 9 + 1 + 3 + 3 + (h.version >= 3 ? 4 : 3) + 3 * std::size_t(shRestCoeffs(h.shDegree));
}

// Inflates the gzip stream into `out` until it holds `limit` bytes or the stream ends; returns
// true when the stream ended. Never produces more than `limit` bytes (decompression bombs).
bool inflateUpTo(const std::string& path, const std::string& data, std::size_t limit, std::string& out)
{
    z_stream z{};
    if (inflateInit2(&z, 16 + MAX_WBITS) != Z_OK) throw InputError(msg(path, ": .spz: cannot start inflate"));
    z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(data.data()));
    z.avail_in = uInt(std::min<std::size_t>(data.size(), UINT32_MAX));
    out.resize(limit);
    z.next_out = reinterpret_cast<Bytef*>(&out[0]);
    z.avail_out = uInt(limit);
    int rc = Z_OK;
    while (rc == Z_OK && z.avail_out > 0) rc = inflate(&z, Z_NO_FLUSH);
    const std::size_t produced = limit - z.avail_out;
    const char* why = z.msg ? z.msg : "stream ends early";
    inflateEnd(&z);
    out.resize(produced);
    if (rc == Z_STREAM_END) return true;
    if (rc == Z_OK && produced == limit) return false;
    throw InputError(msg(path, ": .spz: gzip stream is corrupt or truncated after ", produced,
                         " inflated bytes (", rc == Z_BUF_ERROR ? "stream ends early" : why, ")"));
}

SpzHeader parseHeader(const std::string& path, const std::string& head)
{
    if (head.size() < kSpzHeaderBytes)
        throw InputError(msg(path, ": .spz: inflated data holds ", head.size(), " bytes, less than the 16-byte header"));
    const auto* p = reinterpret_cast<const unsigned char*>(head.data());
    SpzHeader h;
    h.magic = u32le(p);
    h.version = u32le(p + 4);
    h.count = u32le(p + 8);
    h.shDegree = p[12];
    h.fractionalBits = p[13];
    h.flags = p[14];
    if (h.magic != kSpzMagic)
        throw InputError(msg(path, ": gzip data that is not .spz (no NGSP magic after inflating)"));
    if (h.version != 2 && h.version != 3)
        throw InputError(msg(path, ": .spz version ", h.version, " is not supported (versions 2 and 3 are)"));
    if (h.shDegree > 4) throw InputError(msg(path, ": .spz: SH degree ", h.shDegree, " is not in 0..4"));
    if (h.flags & kSpzFlagExtensions)
        throw InputError(msg(path, ": .spz with extensions (flag 0x2) is not supported"));
    if (h.count == 0) throw InputError(msg(path, ": .spz holds no Gaussians"));
    return h;
}

// Decodes the v3 "smallest three" rotation: 2 bits index of the largest component, then three
// 10-bit values (sign bit + 9-bit magnitude in units of 1/sqrt(2)/511), last component first.
void smallestThree(const unsigned char* r, float xyzw[4])
{
    std::uint32_t comp = u32le(r);
    const int largest = int(comp >> 30);
    double sum = 0;
    for (int i = 3; i >= 0; --i) {
        if (i == largest) continue;
        const double v = std::sqrt(0.5) * double(comp & 511u) / 511.0;
        xyzw[i] = float((comp >> 9) & 1u ? -v : v);
        sum += v * v;
        comp >>= 10;
    }
    xyzw[largest] = float(std::sqrt(std::max(0.0, 1.0 - sum)));
}

// v2: x, y, z as u8 in [-1, 1]; w >= 0 from the unit norm.
void firstThree(const unsigned char* r, float xyzw[4])
{
    double sum = 0;
    for (int i = 0; i < 3; ++i) {
        xyzw[i] = float(r[i] / 127.5 - 1.0);
        sum += double(xyzw[i]) * xyzw[i];
    }
    xyzw[3] = float(std::sqrt(std::max(0.0, 1.0 - sum)));
}

GaussianCloud decode(const SpzHeader& h, const std::string& body)
{
    const std::size_t n = h.count;
    const int degree = std::min(h.shDegree, 3), rest = shRestCoeffs(h.shDegree);
    const auto* pos = reinterpret_cast<const unsigned char*>(body.data()) + kSpzHeaderBytes;
    const unsigned char *alpha = pos + 9 * n, *color = alpha + n, *scale = color + 3 * n, *rot = scale + 3 * n;
    const unsigned char* sh = rot + (h.version >= 3 ? 4 : 3) * n;
    GaussianCloud g;
    g.resize(n, degree);
    for (std::size_t i = 0; i < n; ++i) {
        for (int a = 0; a < 3; ++a) {
            const unsigned char* p = pos + 9 * i + 3 * a;
            std::int32_t fixed = std::int32_t(p[0] | p[1] << 8 | p[2] << 16);
            if (fixed & 0x800000) fixed -= 0x1000000; // sign of the 24-bit value
            g.means[3 * i + a] = float(std::ldexp(double(fixed), -h.fractionalBits));
            g.logScales[3 * i + a] = float(scale[3 * i + a] / 16.0 - 10.0);
            g.shOf(i)[a] = float((color[3 * i + a] / 255.0 - 0.5) / kSpzColorScale);
        }
        g.opacities[i] = logitOfU8Alpha(alpha[i]);
        float q[4];
        if (h.version >= 3) smallestThree(rot + 4 * i, q);
        else firstThree(rot + 3 * i, q);
        g.setRotation(i, {q[3], q[0], q[1], q[2]});
        // Coefficient-major, RGB inner, as our layout; band 4 (degree-4 files) is skipped.
        for (int j = 1; j < g.shCoeffs(); ++j)
            for (int c = 0; c < 3; ++c) g.shOf(i)[3 * j + c] = float((sh[(i * rest + j - 1) * 3 + c] - 128.0) / 128.0);
    }
    return g;
}

} // namespace

bool hasSpzMagic(const std::string& data)
{
    const bool gzip = data.size() >= 2 && static_cast<unsigned char>(data[0]) == 0x1f &&
                      static_cast<unsigned char>(data[1]) == 0x8b;
    return gzip || data.compare(0, 4, "NGSP") == 0;
}

GaussianCloud readSpz(const std::string& path, const std::string& data, ReadReport& report)
{
    if (data.compare(0, 4, "NGSP") == 0)
        throw InputError(msg(path, ": .spz version ",
                             data.size() >= 8 ? u32le(reinterpret_cast<const unsigned char*>(data.data()) + 4) : 0,
                             " (uncompressed NGSP header) is not supported (versions 2 and 3 are)"));
    std::string head;
    inflateUpTo(path, data, kSpzHeaderBytes, head);
    const SpzHeader h = parseHeader(path, head);
    const double need = double(kSpzHeaderBytes) + double(h.count) * double(bytesPerGaussian(h));
    if (need > kMaxDeflateRatio * double(data.size()) + 1024.0)
        throw InputError(msg(path, ": .spz header claims ", h.count, " Gaussians (", need,
                             " bytes inflated), more than its ", data.size(), " compressed bytes can hold"));
    std::string body;
    const bool ended = inflateUpTo(path, data, std::size_t(need), body);
    if (body.size() < std::size_t(need))
        throw InputError(msg(path, ": .spz truncated: ", h.count, " Gaussians need ", std::size_t(need),
                             " inflated bytes, the stream holds ", body.size()));
    GaussianCloud g = decode(h, body);
    if (!ended) report.notes.push_back("data after the last .spz Gaussian ignored");
    if (h.shDegree > 3) report.notes.push_back("SH band 4 of the .spz dropped (splatwarp uses degree 0..3)");
    report.format = msg("spz-v", h.version);
    return g;
}

} // namespace splatwarp
