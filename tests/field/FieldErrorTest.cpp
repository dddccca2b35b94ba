#include <gtest/gtest.h>

#include <cstdio>

#include "field/FieldError.h"
#include "field/FieldTestModels.h"
#include "field/RigidMotion.h"

using namespace splatwarp;
using namespace splatwarp::test;

TEST(FieldError, IdentityIsZero)
{
    const GaussianCloud g = randomCloud(300, 2, 3);
    const std::vector<float> pts = randomPoints(3000, 4, 1.4f);
    const FieldErrorReport r = fieldError(g, g, pts.data(), pts.data(), nullptr, pts.size() / 3);
    EXPECT_EQ(r.opacity, 0.0);
    EXPECT_EQ(r.color, 0.0);
    EXPECT_EQ(r.points, 3000u);
    EXPECT_EQ(r.insidePoints + r.outsidePoints, r.points);
    EXPECT_GT(r.insidePoints, 0u);
    EXPECT_GT(r.outsidePoints, 0u);
}

TEST(FieldError, RigidMotionIsNearZeroAndMismatchIsNot)
{
    const GaussianCloud g = randomCloud(300, 2, 7);
    const Mat3d rot = quatToMatrix(Quatd{0.8, 0.3, -0.4, 0.2});
    const Vec3d t(0.5, -1.0, 2.0);
    const GaussianCloud moved = rigidlyMoved(g, rot, t);
    const std::vector<float> rest = randomPoints(3000, 8, 1.4f);
    std::vector<float> warped(rest.size()), rots(9 * (rest.size() / 3));
    for (std::size_t p = 0; p < rest.size() / 3; ++p) {
        const Vec3d x = rot * Vec3d(rest[3 * p], rest[3 * p + 1], rest[3 * p + 2]) + t;
        for (int k = 0; k < 3; ++k) warped[3 * p + std::size_t(k)] = float(x[k]);
        for (int a = 0; a < 9; ++a) rots[9 * p + std::size_t(a)] = float(rot.m[a / 3][a % 3]);
    }
    const FieldErrorReport r = fieldError(g, moved, rest.data(), warped.data(), rots.data(), rest.size() / 3);
    std::printf("  rigid: opacity %.3g colour %.3g\n", r.opacity, r.color);
    // Float rounding of the moved parameters and points. Worst seen: opacity 3e-7, colour 4e-7.
    EXPECT_LT(r.opacity, 1e-5);
    EXPECT_LT(r.color, 1e-5);
    // Without the SH rotation the colour error must show up (the test can fail).
    const FieldErrorReport noRot = fieldError(g, moved, rest.data(), warped.data(), nullptr, rest.size() / 3);
    EXPECT_GT(noRot.color, 0.05);
    EXPECT_LT(noRot.opacity, 1e-5);
    // Unmoved points see the model in the wrong place: large opacity error, inside and outside.
    const FieldErrorReport wrong = fieldError(g, moved, rest.data(), rest.data(), rots.data(), rest.size() / 3);
    EXPECT_GT(wrong.opacityInside, 0.5);
    EXPECT_GT(wrong.opacityOutside, 0.0);
    EXPECT_NEAR(wrong.opacity, wrong.opacityInside + wrong.opacityOutside, 1e-12);
}
