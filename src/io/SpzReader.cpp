/// Niantic `.spz` reader. Versions 2 and 3: a gzip stream holding a 16-byte header and the
/// Gaussians attribute by attribute (positions, alphas, colours, scales, rotations, SH). Version 4:
/// a plain 32-byte NGSP header, extension records, a table of contents and one zstd stream per
/// attribute, in the same order and encoding. Layout and decoding follow github.com/nianticlabs/spz
/// (README, src/cc/load-spz.cc). Values are read without a coordinate conversion, as
/// splat-transform and spz's UNSPECIFIED default do.
#include <zlib.h>
#include <zstd.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <vector>

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
// zstd cannot expand more than 32768:1: a block yields at most 128 KiB and costs at least 4 bytes
// (an RLE block: 3-byte header + 1 byte), RFC 8878 section 3.1.1.2.
constexpr double kMaxZstdRatio = 32768.0;
constexpr std::size_t kNgspHeaderBytes = 32;

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

// What inflateUpTo() found past the bytes it was asked for.
struct InflateEnd {
    bool moreData = false;            ///< the stream inflates to more than `limit` bytes
    std::size_t bytesAfterStream = 0; ///< file bytes after the gzip stream's trailer
};

// Inflates the gzip stream into `out` until it holds `limit` bytes or the stream ends, then looks
// one byte further, so that a stream ending exactly there has its trailer (CRC, length) checked
// and a cut one is refused. Never produces more than `limit` + 1 bytes (decompression bombs).
InflateEnd inflateUpTo(const std::string& path, const std::string& data, std::size_t limit, std::string& out)
{
    z_stream z{};
    if (inflateInit2(&z, 16 + MAX_WBITS) != Z_OK) throw InputError(msg(path, ": .spz: cannot start inflate"));
    z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(data.data()));
    z.avail_in = uInt(std::min<std::size_t>(data.size(), UINT32_MAX));
    out.resize(limit + 1);
    z.next_out = reinterpret_cast<Bytef*>(&out[0]);
    z.avail_out = uInt(limit);
    int rc = Z_OK;
    while (rc == Z_OK && z.avail_out > 0) rc = inflate(&z, Z_NO_FLUSH);
    if (rc == Z_OK) { // `limit` bytes out: one more, or the stream's end
        z.avail_out = 1;
        while (rc == Z_OK && z.avail_out > 0) rc = inflate(&z, Z_NO_FLUSH);
    }
    const std::size_t written = std::size_t(z.total_out);
    const std::size_t consumed = std::size_t(z.total_in);
    const char* why = z.msg ? z.msg : "stream ends early";
    inflateEnd(&z);
    out.resize(std::min(written, limit));
    if (rc == Z_STREAM_END) return {false, data.size() - consumed};
    if (rc == Z_OK && written > limit) return {true, 0};
    throw InputError(msg(path, ": .spz: gzip stream is corrupt or truncated after ", written,
                         " inflated bytes (", rc == Z_BUF_ERROR ? "stream ends early" : why, ")"));
}

void checkCountAndDegree(const std::string& path, const SpzHeader& h)
{
    if (h.shDegree > 4) throw InputError(msg(path, ": .spz: SH degree ", h.shDegree, " is not in 0..4"));
    if (h.count == 0) throw InputError(msg(path, ": .spz holds no Gaussians"));
}

// The first 16 bytes, common to every version (v4 adds the stream count and TOC offset).
SpzHeader headerFields(const unsigned char* p)
{
    SpzHeader h;
    h.magic = u32le(p);
    h.version = u32le(p + 4);
    h.count = u32le(p + 8);
    h.shDegree = p[12];
    h.fractionalBits = p[13];
    h.flags = p[14];
    return h;
}

SpzHeader parseHeader(const std::string& path, const std::string& head)
{
    if (head.size() < kSpzHeaderBytes)
        throw InputError(msg(path, ": .spz: inflated data holds ", head.size(), " bytes, less than the 16-byte header"));
    const auto* p = reinterpret_cast<const unsigned char*>(head.data());
    SpzHeader h = headerFields(p);
    if (h.magic != kSpzMagic)
        throw InputError(msg(path, ": gzip data that is not .spz (no NGSP magic after inflating)"));
    if (h.version != 2 && h.version != 3)
        throw InputError(msg(path, ": .spz version ", h.version,
                             " is not supported in a gzip stream (versions 2 and 3 are; 4 has a plain NGSP header)"));
    if (h.flags & kSpzFlagExtensions)
        throw InputError(msg(path, ": .spz with extensions (flag 0x2) is not supported"));
    checkCountAndDegree(path, h);
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


// Bytes of each attribute stream in file order (positions, alphas, colours, scales, rotations, SH);
// v4 writers leave out empty ones (the SH of degree 0).
std::vector<std::size_t> streamBytes(const SpzHeader& h)
{
    const std::size_t n = h.count;
    std::vector<std::size_t> sizes = {9 * n, n, 3 * n, 3 * n, (h.version >= 3 ? 4 : 3) * n,
                                      3 * std::size_t(shRestCoeffs(h.shDegree)) * n};
    if (sizes.back() == 0) sizes.pop_back();
    return sizes;
}

// Decompresses one zstd stream of exactly `expected` bytes, appending to `out`. The output grows
// with what the stream really yields, so a table of contents that lies allocates nothing.
void unzstdAppend(const std::string& path, int stream, const char* src, std::size_t size, std::size_t expected,
                  std::string& out)
{
    ZSTD_DStream* z = ZSTD_createDStream();
    if (!z) throw InputError(msg(path, ": .spz: cannot start zstd"));
    ZSTD_inBuffer in{src, size, 0};
    const std::size_t start = out.size();
    std::size_t rc = 1;
    while (in.pos < in.size || rc != 0) {
        const std::size_t have = out.size() - start;
        const std::size_t chunk = std::min<std::size_t>(std::max<std::size_t>(have, 1 << 16), expected - have + 1);
        out.resize(out.size() + chunk);
        ZSTD_outBuffer o{&out[start + have], chunk, 0};
        rc = ZSTD_decompressStream(z, &o, &in);
        out.resize(start + have + o.pos);
        if (ZSTD_isError(rc) || out.size() - start > expected || (o.pos == 0 && in.pos == in.size && rc != 0)) {
            const std::string why = ZSTD_isError(rc) ? ZSTD_getErrorName(rc)
                                    : out.size() - start > expected ? "more data than the table of contents says"
                                                                    : "stream ends early";
            ZSTD_freeDStream(z);
            throw InputError(msg(path, ": .spz: zstd stream ", stream, " is corrupt or truncated after ",
                                 out.size() - start, " of ", expected, " bytes (", why, ")"));
        }
    }
    ZSTD_freeDStream(z);
    if (out.size() - start != expected)
        throw InputError(msg(path, ": .spz: zstd stream ", stream, " holds ", out.size() - start, " bytes, ", expected,
                             " expected"));
}

SpzHeader parseNgspHeader(const std::string& path, const std::string& data, std::size_t& numStreams,
                          std::size_t& toc)
{
    if (data.size() < kNgspHeaderBytes)
        throw InputError(msg(path, ": .spz truncated: ", data.size(), " bytes, less than the 32-byte NGSP header"));
    const auto* p = reinterpret_cast<const unsigned char*>(data.data());
    const SpzHeader h = headerFields(p);
    numStreams = p[15];
    toc = u32le(p + 16);
    if (h.version != 4)
        throw InputError(msg(path, ": .spz version ", h.version, " with a plain NGSP header is not supported (version 4 is)"));
    checkCountAndDegree(path, h);
    if (toc < kNgspHeaderBytes || toc > data.size() || numStreams * 16 > data.size() - toc)
        throw InputError(msg(path, ": .spz truncated or corrupt: table of contents at byte ", toc, " (", numStreams,
                             " streams) does not fit in ", data.size(), " bytes"));
    return h;
}

// Version 4: [32-byte header][extension records][TOC: per stream u64 compressed, u64 inflated][streams].
GaussianCloud readSpzV4(const std::string& path, const std::string& data, ReadReport& report)
{
    std::size_t numStreams = 0, toc = 0;
    const SpzHeader h = parseNgspHeader(path, data, numStreams, toc);
    const std::vector<std::size_t> expected = streamBytes(h);
    if (numStreams != expected.size())
        throw InputError(msg(path, ": .spz: ", numStreams, " attribute streams, SH degree ", h.shDegree, " needs ",
                             expected.size()));
    const auto* p = reinterpret_cast<const unsigned char*>(data.data());
    std::string body(kSpzHeaderBytes, '\0'); // decode() reads the attributes after a 16-byte header
    std::size_t offset = toc + 16 * numStreams;
    for (std::size_t s = 0; s < numStreams; ++s) {
        const std::uint64_t packed = u32le(p + toc + 16 * s) | std::uint64_t(u32le(p + toc + 16 * s + 4)) << 32;
        const std::uint64_t inflated = u32le(p + toc + 16 * s + 8) | std::uint64_t(u32le(p + toc + 16 * s + 12)) << 32;
        if (inflated != expected[s])
            throw InputError(msg(path, ": .spz: stream ", s, " inflates to ", inflated, " bytes, ", h.count,
                                 " Gaussians need ", expected[s]));
        if (packed > data.size() - offset)
            throw InputError(msg(path, ": .spz truncated: stream ", s, " needs ", packed, " bytes, ", data.size() - offset,
                                 " left"));
        if (double(inflated) > kMaxZstdRatio * double(packed) + 64.0)
            throw InputError(msg(path, ": .spz header claims ", h.count, " Gaussians (", inflated, " bytes in stream ", s,
                                 "), more than its ", packed, " compressed bytes can hold"));
        unzstdAppend(path, int(s), data.data() + offset, std::size_t(packed), std::size_t(inflated), body);
        offset += std::size_t(packed);
    }
    body.resize(kSpzHeaderBytes + std::size_t(h.count) * bytesPerGaussian(h)); // degree 0: no SH stream
    GaussianCloud g = decode(h, body);
    if (h.flags & kSpzFlagExtensions)
        report.notes.push_back(msg("skipped ", toc - kNgspHeaderBytes,
                                   " bytes of .spz extension records (not applied; a coordinate-system extension "
                                   "would change how the values are meant)"));
    if (offset != data.size()) report.notes.push_back("data after the last .spz stream ignored");
    if (h.shDegree > 3) report.notes.push_back("SH band 4 of the .spz dropped (splatwarp uses degree 0..3)");
    report.format = "spz-v4";
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
    if (data.compare(0, 4, "NGSP") == 0) return readSpzV4(path, data, report);
    std::string head;
    inflateUpTo(path, data, kSpzHeaderBytes, head);
    const SpzHeader h = parseHeader(path, head);
    const double need = double(kSpzHeaderBytes) + double(h.count) * double(bytesPerGaussian(h));
    if (need > kMaxDeflateRatio * double(data.size()) + 1024.0)
        throw InputError(msg(path, ": .spz header claims ", h.count, " Gaussians (", need,
                             " bytes inflated), more than its ", data.size(), " compressed bytes can hold"));
    std::string body;
    const InflateEnd end = inflateUpTo(path, data, std::size_t(need), body);
    if (body.size() < std::size_t(need))
        throw InputError(msg(path, ": .spz truncated: ", h.count, " Gaussians need ", std::size_t(need),
                             " inflated bytes, the stream holds ", body.size()));
    GaussianCloud g = decode(h, body);
    if (end.moreData) report.notes.push_back("inflated data after the last .spz Gaussian ignored");
    if (end.bytesAfterStream > 0)
        report.notes.push_back(msg(end.bytesAfterStream, " bytes after the .spz's gzip stream ignored"));
    if (h.shDegree > 3) report.notes.push_back("SH band 4 of the .spz dropped (splatwarp uses degree 0..3)");
    report.format = msg("spz-v", h.version);
    return g;
}

} // namespace splatwarp
