#include <gtest/gtest.h>

#include <random>

#include "core/SmallMath.h"
#include "sh/SphericalHarmonics.h"

using namespace splatwarp;

namespace {

Mat3d randomRotation(std::mt19937& rng)
{
    std::normal_distribution<double> n(0.0, 1.0);
    Quatd q{n(rng), n(rng), n(rng), n(rng)};
    return quatToMatrix(q);
}

Vec3d randomDirection(std::mt19937& rng)
{
    std::normal_distribution<double> n(0.0, 1.0);
    Vec3d d(n(rng), n(rng), n(rng));
    return d / length(d);
}

std::vector<double> randomCoeffs(std::mt19937& rng, int degree)
{
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    std::vector<double> c(3 * shCoeffCount(degree));
    for (double& v : c) v = u(rng);
    return c;
}

// Independent check of the basis: each band-l function is a harmonic homogeneous polynomial,
// so its values on the sphere satisfy the addition theorem sum_m Y_lm(d)^2 = (2l+1)/(4 pi).
TEST(SphericalHarmonics, BasisSatisfiesAdditionTheorem)
{
    std::mt19937 rng(1);
    for (int t = 0; t < 100; ++t) {
        const Vec3d d = randomDirection(rng);
        double y[16];
        evalShBasis(3, d, y);
        for (int l = 0; l <= 3; ++l) {
            double s = 0;
            for (int m = 0; m < 2 * l + 1; ++m) s += y[l * l + m] * y[l * l + m];
            EXPECT_NEAR(s, (2 * l + 1) / (4 * M_PI), 1e-12) << "band " << l;
        }
    }
}

TEST(SphericalHarmonics, ColourIsHalfPlusSumClampedAtZero)
{
    float coeffs[3] = {float(1.0 / kShC0), float(-2.0 / kShC0), 0.0f};
    const Vec3f c = evalShColor<float>(0, coeffs, Vec3f(0, 0, 1));
    EXPECT_NEAR(c.x, 1.5f, 1e-6);
    EXPECT_EQ(c.y, 0.0f);
    EXPECT_NEAR(c.z, 0.5f, 1e-6);
}

TEST(SphericalHarmonics, RotationPreservesEvaluation)
{
    std::mt19937 rng(2);
    for (int degree = 0; degree <= 3; ++degree)
        for (int t = 0; t < 50; ++t) {
            const Mat3d r = randomRotation(rng);
            const std::vector<double> c = randomCoeffs(rng, degree);
            std::vector<double> rc = c;
            ShRotation(r).apply(degree, rc.data());
            for (int k = 0; k < 5; ++k) {
                const Vec3d d = randomDirection(rng);
                const Vec3d a = evalShSum<double>(degree, c.data(), d);
                const Vec3d b = evalShSum<double>(degree, rc.data(), r * d);
                for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(a[ch], b[ch], 1e-5) << "degree " << degree;
            }
        }
}

TEST(SphericalHarmonics, RotationComposes)
{
    std::mt19937 rng(3);
    for (int t = 0; t < 50; ++t) {
        const Mat3d r1 = randomRotation(rng), r2 = randomRotation(rng);
        const std::vector<double> c = randomCoeffs(rng, 3);
        std::vector<double> once = c, twice = c;
        ShRotation(r1 * r2).apply(3, once.data());
        ShRotation(r2).apply(3, twice.data());
        ShRotation(r1).apply(3, twice.data());
        for (std::size_t i = 0; i < c.size(); ++i) EXPECT_NEAR(once[i], twice[i], 1e-5);
    }
}

TEST(SphericalHarmonics, IdentityAndDegreeZeroInvariance)
{
    std::mt19937 rng(4);
    const std::vector<double> c = randomCoeffs(rng, 3);
    std::vector<double> id = c;
    ShRotation(Mat3d::identity()).apply(3, id.data());
    for (std::size_t i = 0; i < c.size(); ++i) EXPECT_NEAR(id[i], c[i], 1e-12);

    std::vector<double> rc = c;
    ShRotation(randomRotation(rng)).apply(3, rc.data());
    for (int ch = 0; ch < 3; ++ch) EXPECT_EQ(rc[ch], c[ch]) << "band 0 must be untouched";

    // Band matrices are orthogonal (the 3DGS basis is orthonormal up to one constant per band).
    const ShRotation rot(randomRotation(rng));
    for (int l = 1; l <= 3; ++l)
        for (int i = 0; i < 2 * l + 1; ++i)
            for (int j = 0; j < 2 * l + 1; ++j) {
                double s = 0;
                for (int k = 0; k < 2 * l + 1; ++k) s += rot.band(l, i, k) * rot.band(l, j, k);
                EXPECT_NEAR(s, i == j ? 1.0 : 0.0, 1e-10);
            }
}

} // namespace
