#include <gtest/gtest.h>

#include "core/Error.h"
#include "core/GaussianCloud.h"
#include "support/TestGaussians.h"

using namespace splatwarp;

// assign(i, other, j) makes Gaussian i a copy of other's j, every array, and touches nothing else.
TEST(GaussianCloud, AssignCopiesOneGaussianWhole)
{
    const GaussianCloud src = test::threeGaussians();
    GaussianCloud dst = src;
    dst.assign(0, src, 2);
    for (std::size_t i : {std::size_t(0), std::size_t(2)}) {
        for (int a = 0; a < 3; ++a) EXPECT_EQ(dst.mean(i)[a], src.mean(2)[a]);
        EXPECT_EQ(dst.rotation(i).w, src.rotation(2).w);
        EXPECT_EQ(dst.rotation(i).z, src.rotation(2).z);
        EXPECT_EQ(dst.scale(i).y, src.scale(2).y);
        EXPECT_EQ(dst.opacities[i], src.opacities[2]);
        for (int c = 0; c < src.shStride(); ++c) EXPECT_EQ(dst.shOf(i)[c], src.shOf(2)[c]);
    }
    for (int a = 0; a < 3; ++a) EXPECT_EQ(dst.mean(1)[a], src.mean(1)[a]);
    EXPECT_EQ(dst.opacities[1], src.opacities[1]);
    for (int c = 0; c < src.shStride(); ++c) EXPECT_EQ(dst.shOf(1)[c], src.shOf(1)[c]);
    EXPECT_EQ(dst.size(), src.size());
    dst.checkConsistent();
}

// sameGaussian(i, other, j) is bitwise equality of every array of the two Gaussians.
TEST(GaussianCloud, SameGaussianComparesEveryArray)
{
    const GaussianCloud src = test::threeGaussians();
    GaussianCloud dst = src;
    dst.assign(0, src, 2);
    EXPECT_TRUE(dst.sameGaussian(0, src, 2));
    EXPECT_TRUE(dst.sameGaussian(1, src, 1));
    EXPECT_FALSE(dst.sameGaussian(0, src, 0));
    for (auto change : {+[](GaussianCloud& g) { g.means[1] += 1e-6f; }, +[](GaussianCloud& g) { g.rotations[3] += 1e-6f; },
                        +[](GaussianCloud& g) { g.logScales[2] += 1e-6f; }, +[](GaussianCloud& g) { g.opacities[0] += 1e-6f; },
                        +[](GaussianCloud& g) { g.sh[std::size_t(g.shStride() - 1)] += 1e-6f; }}) {
        GaussianCloud c = src;
        change(c);
        EXPECT_FALSE(c.sameGaussian(0, src, 0));
        EXPECT_TRUE(c.sameGaussian(1, src, 1));
    }
}

// erase(drop) keeps the other Gaussians whole and in order; eraseRows() keeps an array beside it in step.
TEST(GaussianCloud, EraseKeepsTheOthersWholeAndInOrder)
{
    const GaussianCloud src = test::threeGaussians();
    GaussianCloud g = src;
    std::vector<int> tags{10, 11, 12, 20, 21, 22};
    const std::vector<std::uint8_t> drop{0, 1, 0};
    g.erase(drop);
    eraseRows(tags, drop, 2);
    ASSERT_EQ(g.size(), 2u);
    g.checkConsistent();
    EXPECT_TRUE(g.sameGaussian(0, src, 0));
    EXPECT_TRUE(g.sameGaussian(1, src, 2));
    EXPECT_EQ(tags, (std::vector<int>{10, 11, 21, 22}));
    EXPECT_THROW(g.erase({1}), InputError);
}
