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
    expectRefused(dir, gzip(raw.substr(0, 8)), "less than the 16-byte header");
    expectRefused(dir, gzip("ply\nthis is not spz at all, only gzip of some text"), "not .spz");
    std::string v = raw;
    putU32(v, 4, 4);
    expectRefused(dir, gzip(v), "version 4 is not supported");
    putU32(v, 4, 1);
    expectRefused(dir, gzip(v), "version 1 is not supported");
    expectRefused(dir, std::string("NGSP\x04\0\0\0 plain header of a version 4 file", 40), "version 4");
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

TEST(SpzReader, CliConvertsSpzToPly)
{
    TempDir dir;
    const std::string out = dir.file("out.ply");
    ASSERT_EQ(runCli("-q convert " + fixture("random200-sh3.v3.spz") + " " + out), 0);
    const GaussianCloud a = readGaussians(fixture("random200-sh3.v3.spz")), b = readGaussians(out);
    EXPECT_EQ(a.means, b.means);
    EXPECT_EQ(a.opacities, b.opacities);
}
