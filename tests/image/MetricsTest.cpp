#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "core/Error.h"
#include "image/ImageTestUtil.h"
#include "image/Metrics.h"

namespace splatwarp {
namespace {

using test::randomImage;

/// SSIM straight from the definition: weighted statistics of every 11x11 window (Gaussian
/// weights, sigma 1.5, normalised), in double.
double naiveSsim(const Image& a, const Image& b)
{
    const int n = 11, r = 5;
    double w[11][11], norm = 0;
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) norm += (w[i][j] = std::exp(-((i - r) * (i - r) + (j - r) * (j - r)) / (2 * 1.5 * 1.5)));
    const double c1 = 0.01 * 0.01, c2 = 0.03 * 0.03;
    double total = 0;
    for (int c = 0; c < 3; ++c) {
        double sum = 0;
        int count = 0;
        for (int y = r; y < a.height - r; ++y)
            for (int x = r; x < a.width - r; ++x) {
                double ma = 0, mb = 0;
                for (int i = 0; i < n; ++i)
                    for (int j = 0; j < n; ++j) {
                        ma += w[i][j] / norm * a.at(x + j - r, y + i - r, c);
                        mb += w[i][j] / norm * b.at(x + j - r, y + i - r, c);
                    }
                double va = 0, vb = 0, cov = 0;
                for (int i = 0; i < n; ++i)
                    for (int j = 0; j < n; ++j) {
                        const double da = a.at(x + j - r, y + i - r, c) - ma, db = b.at(x + j - r, y + i - r, c) - mb;
                        va += w[i][j] / norm * da * da;
                        vb += w[i][j] / norm * db * db;
                        cov += w[i][j] / norm * da * db;
                    }
                sum += (2 * ma * mb + c1) * (2 * cov + c2) / ((ma * ma + mb * mb + c1) * (va + vb + c2));
                ++count;
            }
        total += sum / count;
    }
    return total / 3;
}

// E[a^2] - E[a]^2 cancelled with display values near 1e35: SSIM came out at -3.9e16.
TEST(MetricsTest, SsimStaysWithinItsRangeForHugeValues)
{
    Image a = randomImage(24, 24, 3, 5), b = randomImage(24, 24, 3, 6);
    for (float& v : a.pixels) v = 1e35f + v * 1e30f;
    for (float& v : b.pixels) v = 1e36f * v;
    const double s = ssim(a, b);
    EXPECT_TRUE(s >= -1.0 && s <= 1.0) << s;
    EXPECT_TRUE(std::isfinite(psnr(a, b)));
}

TEST(MetricsTest, IdenticalImages)
{
    const Image a = randomImage(20, 15, 3, 1);
    EXPECT_TRUE(std::isinf(psnr(a, a)));
    EXPECT_NEAR(ssim(a, a), 1.0, 1e-12);
}

TEST(MetricsTest, ConstantOffsetPsnrClosedForm)
{
    // Every value differs by d: MSE = d^2, PSNR = -20 log10(d).
    Image a(16, 12, 4, 0.25f), b(16, 12, 4, 0.25f);
    const float d = 0.125f; // exact in binary
    for (int y = 0; y < 12; ++y)
        for (int x = 0; x < 16; ++x) {
            for (int c = 0; c < 3; ++c) b.at(x, y, c) = a.at(x, y, c) + d;
            b.at(x, y, 3) = 0.0f; // alpha is not compared
        }
    EXPECT_NEAR(psnr(a, b), -20.0 * std::log10(0.125), 1e-9);
    EXPECT_NEAR(psnr(a, b, 255.0), -20.0 * std::log10(0.125 / 255.0), 1e-9);
}

TEST(MetricsTest, ConstantImagesSsimClosedForm)
{
    // No variance: SSIM = (2 p q + C1) / (p^2 + q^2 + C1) at every window.
    const double p = 0.3, q = 0.6, c1 = 1e-4;
    const Image a(12, 12, 3, float(p)), b(12, 12, 3, float(q));
    const double pf = float(p), qf = float(q);
    EXPECT_NEAR(ssim(a, b), (2 * pf * qf + c1) / (pf * pf + qf * qf + c1), 1e-9);
}

TEST(MetricsTest, SsimMatchesDirectDefinition)
{
    const Image a = randomImage(23, 17, 3, 7);
    Image b = a;
    std::mt19937 gen(11);
    std::normal_distribution<float> noise(0.0f, 0.1f);
    for (float& v : b.pixels) v = std::min(1.0f, std::max(0.0f, v + noise(gen)));
    const double fast = ssim(a, b), slow = naiveSsim(a, b);
    EXPECT_NEAR(fast, slow, 1e-9); // measured ~1e-15
    EXPECT_GT(fast, 0.1);
    EXPECT_LT(fast, 0.99);
}

TEST(MetricsTest, RejectsMismatchedOrTinyImages)
{
    EXPECT_THROW(psnr(Image(4, 4, 3), Image(4, 5, 3)), InputError);
    EXPECT_THROW(ssim(Image(10, 10, 3), Image(10, 10, 3)), InputError);
}

} // namespace
} // namespace splatwarp
