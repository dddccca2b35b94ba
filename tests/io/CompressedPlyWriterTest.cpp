/// Compressed PLY writer: read back by our reader, each Gaussian (in the writer's Morton order)
/// equals the source within the quantisation of its chunk, derived from the bit depths and the
/// chunk's own min/max, as the writer computes them.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "core/Error.h"
#include "io/FormatReaders.h"
#include "io/GaussianIO.h"
#include "sh/SphericalHarmonics.h"
#include "support/TestSupport.h"

using namespace splatwarp;
using namespace splatwarp::test;

namespace {

std::string fixture(const std::string& name) { return std::string(SPLATWARP_SOURCE_DIR) + "/tests/io/data/" + name; }

double sigmoidD(double x) { return 1 / (1 + std::exp(-x)); }

// Half a code of `bits` over [lo, hi] (a value outside the range is clamped: none here), plus
// float rounding of the stored bounds and of the lerp.
double step(double lo, double hi, int bits)
{
    return 0.5 * (hi - lo) / double((1u << bits) - 1u) + 4e-7 * (1 + std::max(std::fabs(lo), std::fabs(hi)));
}

} // namespace

TEST(CompressedPlyWriter, ReadsBackWithinEachChunksQuantisation)
{
    TempDir dir;
    GaussianCloud src = readGaussians(fixture("random200-sh3.ply"));
    // 600 Gaussians: three chunks, the last one partial.
    GaussianCloud big;
    big.resize(0, 3);
    for (int k = 0; k < 3; ++k)
        for (std::size_t i = 0; i < src.size(); ++i) {
            big.append(src, i);
            big.means[3 * (big.size() - 1)] += float(k) * 10.0f;
        }
    const std::string path = dir.file("m.compressed.ply");
    writeGaussians(path, big);
    ReadReport report;
    const GaussianCloud back = readGaussians(path, {}, &report);
    EXPECT_EQ(report.format, "ply-compressed");
    ASSERT_EQ(back.size(), big.size());
    ASSERT_EQ(back.shDegree, 3);
    const std::vector<std::size_t> order = compressedPlyOrder(big);
    const int bits[3] = {11, 10, 11};
    for (std::size_t c = 0; c * 256 < order.size(); ++c) {
        const std::size_t begin = c * 256, end = std::min(order.size(), begin + 256);
        for (int q = 0; q < 9; ++q) { // centre x y z, log scale x y z, colour r g b
            const auto value = [&](std::size_t i) {
                return q < 3 ? big.means[3 * i + q] : q < 6 ? big.logScales[3 * i + q - 3] : 0.5 + kShC0 * big.shOf(i)[q - 6];
            };
            double lo = value(order[begin]), hi = lo;
            for (std::size_t k = begin; k < end; ++k) lo = std::min(lo, value(order[k])), hi = std::max(hi, value(order[k]));
            const double tol = q < 6 ? step(lo, hi, bits[q % 3]) : step(lo, hi, 8);
            for (std::size_t k = begin; k < end; ++k) {
                const double got = q < 3 ? back.means[3 * k + q] : q < 6 ? back.logScales[3 * k + q - 3]
                                                                      : 0.5 + kShC0 * back.shOf(k)[q - 6];
                ASSERT_NEAR(got, value(order[k]), tol) << "chunk " << c << " quantity " << q << " k " << k;
            }
        }
        for (std::size_t k = begin; k < end; ++k) {
            const std::size_t i = order[k];
            ASSERT_NEAR(sigmoidD(back.opacities[k]), sigmoidD(big.opacities[i]), 0.5 / 255 + 1e-6) << k;
            // uchar trunc((f / 8 + 0.5) * 256) read back at the code's centre: half a code of 8/256,
            // except the end codes 0 and 255, which read as -4 and +4 exactly (a whole code).
            for (int j = 3; j < big.shStride(); ++j) {
                const double tol = (std::fabs(big.shOf(i)[j]) < 3.9 ? 4.0 : 8.0) / 256 + 1e-6;
                ASSERT_NEAR(back.shOf(k)[j], big.shOf(i)[j], tol) << k << " sh " << j;
            }
            const Quatf a = big.rotation(i), b = back.rotation(k);
            const double na = std::sqrt(double(a.w) * a.w + double(a.x) * a.x + double(a.y) * a.y + double(a.z) * a.z);
            const double dot = std::fabs(a.w * b.w + a.x * b.x + a.y * b.y + a.z * b.z) / na;
            // Stored components off by d = half a 10-bit code of sqrt(2); the derived largest one
            // (>= 1/2, the others sum to <= 1.5 in magnitude) by <= 3d: |dq|^2 <= 12 d^2 and
            // 1 - cos = |dq|^2 / 2, plus float rounding.
            const double d = 0.5 * std::sqrt(2.0) / 1023;
            ASSERT_GT(dot, 1 - 6 * d * d - 1e-6) << k;
        }
    }
}
