/// `.spz` reader against files written by two independent encoders (tests/io/data/README.md):
/// decoded values equal the source model within the format's quantisation, derived below from its
/// bit depths; broken files are refused with InputError naming the file.
#include <gtest/gtest.h>
#include <zlib.h>

#include <cmath>
#include <cstring>

#include "PlyTestFiles.h"
#include "core/Error.h"
#include "io/GaussianIO.h"
#include "support/TestSupport.h"

using namespace splatwarp;
using namespace splatwarp::test;

namespace {

std::string fixture(const std::string& name) { return std::string(SPLATWARP_SOURCE_DIR) + "/tests/io/data/" + name; }

// Quantisation steps of the format (nianticlabs/spz README): positions 24-bit fixed point with
// 12 fractional bits (the writers' choice, in the header), log scales u8 in steps of 1/16,
// colours u8 of f_dc * 0.15, alpha u8 of sigmoid(opacity), SH u8 in steps of 1/128 rounded to
// 5 bits (band 1) or 4 bits (bands 2, 3) by both writers' defaults.
const double kPosTol = 0.5 / 4096 + 1e-6; // half a step, plus float32 rounding at |x| <= 4
const double kLogScaleTol = 0.5 / 16 + 1e-6;
const double kDcTol = 0.5 / (255 * 0.15) + 1e-6;
const double kAlphaTol = 0.5 / 255 + 1e-6;
const double kSh1Tol = (4 + 0.5) / 128 + 1e-6;  // bucket of 8 (5 bits): off by up to 4 codes + rounding
const double kShRestTol = (8 + 0.5) / 128 + 1e-6; // bucket of 16 (4 bits): off by up to 8 codes + rounding

double sigmoid(double x) { return 1 / (1 + std::exp(-x)); }

// Rotation tolerance per stored component: v3 stores 9-bit magnitudes in units of
// sqrt(1/2)/511, v2 u8 in units of 1/127.5. The derived component L (w in v2, the largest in v3)
// satisfies |L - L'| <= sqrt(|L^2 - L'^2|) <= sqrt(2 * sum|q_i| * d + 3 d^2) <= sqrt(2 sqrt(3) d + 3 d^2).
void expectRotationsClose(const GaussianCloud& src, const GaussianCloud& dec, int version)
{
    const double d = version >= 3 ? 0.5 * std::sqrt(0.5) / 511 : 0.5 / 127.5;
    const double derived = std::sqrt(2 * std::sqrt(3.0) * d + 3 * d * d);
    for (std::size_t i = 0; i < src.size(); ++i) {
        double q[4], n = 0, dot = 0;
        for (int a = 0; a < 4; ++a) n += double(src.rotations[4 * i + a]) * src.rotations[4 * i + a];
        for (int a = 0; a < 4; ++a) q[a] = src.rotations[4 * i + a] / std::sqrt(n);
        for (int a = 0; a < 4; ++a) dot += q[a] * dec.rotations[4 * i + a];
        const double sign = dot < 0 ? -1 : 1; // q and -q are one rotation
        for (int a = 0; a < 4; ++a)
            ASSERT_NEAR(sign * q[a], dec.rotations[4 * i + a], std::max(d, derived) + 1e-6) << "Gaussian " << i << " rot " << a;
    }
}

void expectDecodesSource(const std::string& spz, int version)
{
    const GaussianCloud src = readGaussians(fixture("random200-sh3.ply"));
    ReadReport report;
    const GaussianCloud dec = readGaussians(fixture(spz), {}, &report);
    EXPECT_EQ(report.format, "spz-v" + std::to_string(version));
    ASSERT_EQ(dec.size(), src.size());
    ASSERT_EQ(dec.shDegree, 3);
    for (std::size_t i = 0; i < src.size(); ++i) {
        for (int a = 0; a < 3; ++a) {
            ASSERT_NEAR(dec.means[3 * i + a], src.means[3 * i + a], kPosTol) << i;
            ASSERT_NEAR(dec.logScales[3 * i + a], src.logScales[3 * i + a], kLogScaleTol) << i;
        }
        ASSERT_NEAR(sigmoid(dec.opacities[i]), sigmoid(src.opacities[i]), kAlphaTol) << i;
        for (int j = 0; j < src.shCoeffs(); ++j)
            for (int c = 0; c < 3; ++c) {
                const double tol = j == 0 ? kDcTol : j < 4 ? kSh1Tol : kShRestTol;
                ASSERT_NEAR(dec.shOf(i)[3 * j + c], src.shOf(i)[3 * j + c], tol) << i << " coeff " << j << " ch " << c;
            }
    }
    expectRotationsClose(src, dec, version);
}

std::string gunzip(const std::string& gz)
{
    std::string out(1 << 20, '\0');
    z_stream z{};
    EXPECT_EQ(inflateInit2(&z, 16 + MAX_WBITS), Z_OK);
    z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(gz.data()));
    z.avail_in = uInt(gz.size());
    z.next_out = reinterpret_cast<Bytef*>(&out[0]);
    z.avail_out = uInt(out.size());
    EXPECT_EQ(inflate(&z, Z_FINISH), Z_STREAM_END);
    out.resize(z.total_out);
    inflateEnd(&z);
    return out;
}

std::string gzip(const std::string& raw)
{
    std::string out(raw.size() + 1024, '\0');
    z_stream z{};
    EXPECT_EQ(deflateInit2(&z, 9, Z_DEFLATED, 16 + MAX_WBITS, 8, Z_DEFAULT_STRATEGY), Z_OK);
    z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(raw.data()));
    z.avail_in = uInt(raw.size());
    z.next_out = reinterpret_cast<Bytef*>(&out[0]);
    z.avail_out = uInt(out.size());
    EXPECT_EQ(deflate(&z, Z_FINISH), Z_STREAM_END);
    out.resize(z.total_out);
    deflateEnd(&z);
    return out;
}

void putU32(std::string& s, std::size_t at, std::uint32_t v)
{
    for (int b = 0; b < 4; ++b) s[at + b] = char((v >> (8 * b)) & 0xff);
}

// readGaussians on `bytes` throws InputError naming the file and containing `part`.
void expectRefused(const TempDir& dir, const std::string& bytes, const std::string& part)
{
    const std::string path = dir.file("bad.spz");
    writeBytes(path, bytes);
    const std::string m = inputErrorMessage([&] { readGaussians(path); });
    EXPECT_NE(m.find(path), std::string::npos) << m;
    EXPECT_NE(m.find(part), std::string::npos) << "'" << part << "' not in: " << m;
}

} // namespace

TEST(SpzReader, Version3FromSplatTransformMatchesSource) { expectDecodesSource("random200-sh3.v3.spz", 3); }

TEST(SpzReader, Version2FromSpzJsMatchesSource) { expectDecodesSource("random200-sh3.v2.spz", 2); }

TEST(SpzReader, Version4FromSplatTransformMatchesSource) { expectDecodesSource("random200-sh3.v4.spz", 4); }

// Our encoder quantises as the official one (splat-transform writes through its WASM): the
// inflated v3 payload and the v4 header are byte for byte the reference's, and the v4 streams
// decode to the same values bit for bit.
TEST(SpzWriter, BytesEqualTheReferenceEncoders)
{
    const GaussianCloud src = readGaussians(fixture("random200-sh3.ply"));
    EXPECT_EQ(gunzip(encodeSpz("x.spz", src, 3)), gunzip(readBytes(fixture("random200-sh3.v3.spz"))));
    const std::string ours = encodeSpz("x.spz", src, 4), theirs = readBytes(fixture("random200-sh3.v4.spz"));
    EXPECT_EQ(ours.substr(0, 32), theirs.substr(0, 32));
    const GaussianCloud a = readGaussiansFromBytes("ours", ours), b = readGaussiansFromBytes("theirs", theirs);
    ASSERT_EQ(a.size(), b.size());
    for (std::size_t i = 0; i < a.size(); ++i) ASSERT_TRUE(a.sameGaussian(i, b, i)) << i;
}

TEST(SpzWriter, LargeCoordinatesGetFewerFractionalBitsAndNaNIsRefused)
{
    GaussianCloud g = readGaussians(fixture("random200-sh3.ply"));
    g.means[0] = 3000.0f; // beyond 2048 = 2^23 / 2^12: 11 fractional bits
    for (int version : {3, 4}) {
        const GaussianCloud back = readGaussiansFromBytes("x", encodeSpz("x.spz", g, version));
        EXPECT_NEAR(back.means[0], 3000.0f, 0.5 / 2048 + 1e-6);
        EXPECT_NEAR(back.means[1], g.means[1], 0.5 / 2048 + 1e-6);
    }
    g.opacities[7] = std::nanf("");
    const std::string m = inputErrorMessage([&] { encodeSpz("out.spz", g, 4); });
    EXPECT_NE(m.find("out.spz: refusing to write Gaussian 7: property 'opacity'"), std::string::npos) << m;
    EXPECT_THROW(encodeSpz("out.spz", g, 2), UsageError);
}

// Version 4 files cut, lying or inflating beyond their table of contents are InputErrors naming
// the file, before any allocation their claims would need.
TEST(SpzReader, BrokenVersion4FilesAreInputErrors)
{
    TempDir dir;
    const std::string v4 = readBytes(fixture("random200-sh3.v4.spz"));
    ASSERT_EQ(std::string(v4, 0, 4), "NGSP");
    expectRefused(dir, v4.substr(0, 20), "less than the 32-byte NGSP header");
    expectRefused(dir, v4.substr(0, 40), "table of contents");
    expectRefused(dir, v4.substr(0, v4.size() - 10), "truncated");
    std::string bad = v4;
    putU32(bad, 4, 5);
    expectRefused(dir, bad, "version 5 with a plain NGSP header is not supported");
    bad = v4;
    bad[15] = 5; // stream count
    expectRefused(dir, bad, "5 attribute streams");
    bad = v4;
    putU32(bad, 8, 0xffffffffu); // count: every stream then disagrees with the table of contents
    expectRefused(dir, bad, "inflates to");
    bad = v4;
    bad[32 + 16 * 2] = char(bad[32 + 16 * 2] ^ 0x40); // a compressed size that leaves the file
    expectRefused(dir, bad, "stream 2");
    bad = v4;
    std::size_t sh = 32 + 16 * 6; // the SH stream's frame starts after the TOC and streams 0..4
    for (int s = 0; s < 5; ++s) sh += std::uint8_t(v4[32 + 16 * s]) | std::uint8_t(v4[33 + 16 * s]) << 8;
    bad[sh] = char(bad[sh] ^ 0xff); // its zstd magic
    expectRefused(dir, bad, "zstd stream 5 is corrupt");
    // A bomb: a header whose count needs 4 GB in a 200-byte file is refused by zstd's ratio bound.
    std::string bomb(32 + 16 * 5 + 40, '\0');
    bomb.replace(0, 4, "NGSP");
    putU32(bomb, 4, 4);
    putU32(bomb, 8, 400000000u);
    bomb[15] = 5;
    putU32(bomb, 16, 32);
    const std::uint64_t n = 400000000u, sizes[5] = {9 * n, n, 3 * n, 3 * n, 4 * n};
    for (int s = 0; s < 5; ++s) {
        putU32(bomb, 32 + 16 * s, 8);
        putU32(bomb, 32 + 16 * s + 8, std::uint32_t(sizes[s]));
        putU32(bomb, 32 + 16 * s + 12, std::uint32_t(sizes[s] >> 32));
    }
    expectRefused(dir, bomb, "more than its 8 compressed bytes can hold");
}

TEST(SpzReader, ZstdStreamLongerThanItsTableOfContentsIsRefused)
{
    // A real zstd stream that inflates to more than the TOC says: decoding stops at the claim.
    const GaussianCloud src = readGaussians(fixture("random200-sh3.ply"));
    std::string v4 = encodeSpz("x.spz", withShDegree(src, 0), 4);
    ASSERT_EQ(v4[15], 5);
    putU32(v4, 8, 100); // 100 Gaussians: every stream holds twice that
    for (int s = 0; s < 5; ++s) {
        const std::uint32_t per[5] = {9, 1, 3, 3, 4};
        putU32(v4, 32 + 16 * s + 8, 100 * per[s]);
    }
    TempDir dir;
    expectRefused(dir, v4, "more data than the table of contents says");
}

TEST(SpzReader, OwnGzipOfTheSameBytesDecodesIdentically)
{
    // The test's gzip helper is what the bad-input cases below rely on.
    const std::string raw = gunzip(readBytes(fixture("random200-sh3.v3.spz")));
    TempDir dir;
    writeBytes(dir.file("re.spz"), gzip(raw));
    const GaussianCloud a = readGaussians(fixture("random200-sh3.v3.spz")), b = readGaussians(dir.file("re.spz"));
    EXPECT_EQ(a.means, b.means);
    EXPECT_EQ(a.sh, b.sh);
    EXPECT_EQ(a.rotations, b.rotations);
}

TEST(SpzReader, BrokenFilesAreInputErrors)
{
    TempDir dir;
    const std::string gz = readBytes(fixture("random200-sh3.v3.spz"));
    const std::string raw = gunzip(gz);
    ASSERT_EQ(raw.size(), 16u + 200u * 65u);
    expectRefused(dir, gz.substr(0, gz.size() / 2), "truncated");
    expectRefused(dir, gz.substr(0, 2), "truncated");
    // Cut inside the gzip trailer (CRC-32, length) or the last deflate block: every Gaussian's
    // bytes may already be out, yet the file is not whole.
    for (std::size_t cut = 1; cut <= 9; ++cut) expectRefused(dir, gz.substr(0, gz.size() - cut), "truncated");
    expectRefused(dir, gzip(raw.substr(0, 8)), "less than the 16-byte header");
    expectRefused(dir, gzip("ply\nthis is not spz at all, only gzip of some text"), "not .spz");
    std::string v = raw;
    putU32(v, 4, 4);
    expectRefused(dir, gzip(v), "version 4 is not supported");
    putU32(v, 4, 1);
    expectRefused(dir, gzip(v), "version 1 is not supported");
    expectRefused(dir, std::string("NGSP\x04\0\0\0 plain header of a version 4 file", 40), "SH degree 105");
    std::string more = raw;
    putU32(more, 8, 201); // one Gaussian more than the data holds
    expectRefused(dir, gzip(more), "truncated: 201 Gaussians need");
    putU32(more, 8, 0xffffffffu); // a decompression bomb's claim: refused before allocating
    expectRefused(dir, gzip(more), "more than its");
    std::string ext = raw;
    ext[14] = 2;
    expectRefused(dir, gzip(ext), "extensions");
    std::string deg = raw;
    deg[12] = 5;
    expectRefused(dir, gzip(deg), "SH degree 5");
}

TEST(SpzReader, DataPastTheGaussiansIsANote)
{
    TempDir dir;
    const std::string gz = readBytes(fixture("random200-sh3.v3.spz"));
    const auto notesOf = [&](const std::string& bytes) {
        writeBytes(dir.file("n.spz"), bytes);
        ReadReport report;
        EXPECT_EQ(readGaussians(dir.file("n.spz"), {}, &report).size(), 200u);
        std::string all;
        for (const std::string& n : report.notes) all += n + ";";
        return all;
    };
    EXPECT_EQ(notesOf(gz), "");
    EXPECT_EQ(notesOf(gz + "junk"), "4 bytes after the .spz's gzip stream ignored;");
    EXPECT_EQ(notesOf(gzip(gunzip(gz) + "xyz")), "inflated data after the last .spz Gaussian ignored;");
}

TEST(SpzReader, CliConvertsSpzToPly)
{
    TempDir dir;
    const std::string out = dir.file("out.ply");
    ASSERT_EQ(runCli("-q convert " + fixture("random200-sh3.v3.spz") + " " + out), 0);
    const GaussianCloud a = readGaussians(fixture("random200-sh3.v3.spz")), b = readGaussians(out);
    EXPECT_EQ(a.means, b.means);
    EXPECT_EQ(a.opacities, b.opacities);
}

// The PlayCanvas engine's example (examples/assets/splats/biker.spz, a v4 file), when someone has
// put it into ../shared/data/splats: its count and degree, and values inside the header's ranges.
TEST(SpzReader, EngineBikerVersion4)
{
    SPLATWARP_REQUIRE_DATA(biker, "splats/biker.spz");
    ReadReport report;
    const GaussianCloud g = readGaussians(biker, {}, &report);
    EXPECT_EQ(report.format, "spz-v4");
    EXPECT_EQ(g.size(), 152746u);
    EXPECT_EQ(g.shDegree, 0);
    for (float v : g.means) ASSERT_LE(std::fabs(v), 2048.0f);
}
