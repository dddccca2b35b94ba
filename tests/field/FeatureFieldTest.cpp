#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>

#include "core/Error.h"
#include "field/FeatureField.h"
#include "field/FieldTestModels.h"

using namespace splatwarp;
using namespace splatwarp::test;

namespace {

// Float evaluation relative to O (>= the summed |w H| since |H| <= 1). Worst seen: see the
// printed line (about 1e-6 with the Cholesky form).
constexpr double kRelTol = 1e-5;

void checkAgainstReference(int degree, float filterVariance, std::uint32_t seed)
{
    const GaussianCloud g = randomCloud(400, degree, seed);
    const std::vector<float> pts = randomPoints(1500, seed + 1, 1.3f);
    const std::size_t m = pts.size() / 3;
    FeatureOptions opt;
    opt.filterVariance = filterVariance;
    std::vector<float> f(m * std::size_t(g.shStride())), o(m);
    FeatureStats stats;
    evaluateFeatures(g, pts.data(), m, opt, f.data(), o.data(), &stats);
    const ReferenceFeatures ref = referenceFeatures(g, pts, filterVariance, opt.cutoff);

    // No pair above the cutoff is missed and none below is added (up to float rounding at the cutoff).
    EXPECT_GE(stats.pairsContributing, ref.sure);
    EXPECT_LE(stats.pairsContributing, ref.possible);
    EXPECT_GT(ref.sure, m); // the test is not vacuous
    EXPECT_LT(stats.pairsTested, m * g.size() / 4) << "binning should prune most pairs";

    double worst = 0;
    for (std::size_t p = 0; p < m; ++p) {
        // scale: the sum of |terms| (bounded by O * max|H| <= O with |H| <= 1)
        const double scale = ref.o[p] + 1e-30;
        const double errO = std::fabs(o[p] - ref.o[p]);
        EXPECT_LE(errO, kRelTol * scale + ref.oBand[p]) << "point " << p;
        if (ref.oBand[p] == 0) worst = std::max(worst, errO / scale);
        for (int s = 0; s < g.shStride(); ++s) {
            const std::size_t k = p * std::size_t(g.shStride()) + std::size_t(s);
            const double errF = std::fabs(f[k] - ref.f[k]);
            EXPECT_LE(errF, kRelTol * scale + ref.fBand[k]) << "point " << p << " coeff " << s;
            if (ref.fBand[k] == 0) worst = std::max(worst, errF / scale);
        }
    }
    std::printf("  degree %d filter %g: worst relative error %.3g\n", degree, double(filterVariance), worst);
}

} // namespace

TEST(FeatureField, MatchesNaiveDoubleSh0)
{
    checkAgainstReference(0, 0.0f, 11);
}

TEST(FeatureField, MatchesNaiveDoubleSh3)
{
    checkAgainstReference(3, 0.0f, 12);
}

TEST(FeatureField, MatchesNaiveDoubleWithFilter)
{
    checkAgainstReference(1, 0.2f * 0.02f * 0.02f, 13);
}

TEST(FeatureField, ThreadedEqualsSerialBitForBit)
{
    const GaussianCloud g = randomCloud(2000, 2, 5);
    const std::vector<float> pts = randomPoints(20000, 6, 1.2f);
    const std::size_t m = pts.size() / 3;
    FeatureOptions opt;
    std::vector<float> f1(m * std::size_t(g.shStride())), o1(m), f2(f1.size()), o2(m);
    evaluateFeatures(g, pts.data(), m, opt, f1.data(), o1.data());
    opt.threaded = false;
    evaluateFeatures(g, pts.data(), m, opt, f2.data(), o2.data());
    EXPECT_EQ(0, std::memcmp(f1.data(), f2.data(), f1.size() * sizeof(float)));
    EXPECT_EQ(0, std::memcmp(o1.data(), o2.data(), o1.size() * sizeof(float)));
}

TEST(FeatureField, MassOfWellSeparatedGaussians)
{
    // Four Gaussians 2 apart along x; the lattice sum of O times the voxel volume must equal
    // sum alpha (2 pi)^{3/2} s1 s2 s3 times the fraction of a 3D normal inside the cutoff
    // radius r (alpha e^{-r^2/2} = cutoff): 1 - [erfc(r/sqrt2) + sqrt(2/pi) r e^{-r^2/2}].
    GaussianCloud g = randomCloud(4, 0, 21, 1.0f, 0.08f, 0.2f);
    for (std::size_t i = 0; i < 4; ++i) g.setMean(i, Vec3f(2.0f * float(i), 0.0f, 0.0f));
    double expected = 0;
    for (std::size_t i = 0; i < 4; ++i) {
        const Vec3f s = g.scale(i);
        const double alpha = g.alpha(i);
        const double r = extentRadius(alpha, double(kDefaultCutoff));
        const double tail = std::erfc(r / std::sqrt(2.0)) + std::sqrt(2.0 / M_PI) * r * std::exp(-0.5 * r * r);
        expected += alpha * std::pow(2 * M_PI, 1.5) * double(s.x) * double(s.y) * double(s.z) * (1.0 - tail);
    }
    const float h = 0.02f;
    std::vector<float> pts;
    for (float x = -1.0f; x <= 7.0f; x += h)
        for (float y = -1.0f; y <= 1.0f; y += h)
            for (float z = -1.0f; z <= 1.0f; z += h) pts.insert(pts.end(), {x, y, z});
    std::vector<float> o(pts.size() / 3);
    evaluateFeatures(g, pts.data(), o.size(), FeatureOptions{}, nullptr, o.data());
    double mass = 0;
    for (float v : o) mass += v;
    mass *= double(h) * h * h;
    std::printf("  mass ratio %.5f\n", mass / expected);
    // Lattice quadrature of a truncated Gaussian (h/s <= 0.25). Worst seen: 0.3 %.
    EXPECT_NEAR(mass / expected, 1.0, 0.01);
}

TEST(FeatureField, RejectsBadOptions)
{
    const GaussianCloud g = randomCloud(3, 0, 1);
    const float p[3] = {0, 0, 0};
    float o = 0;
    FeatureOptions opt;
    opt.cutoff = 0.0f;
    EXPECT_THROW(evaluateFeatures(g, p, 1, opt, nullptr, &o), InputError);
}
