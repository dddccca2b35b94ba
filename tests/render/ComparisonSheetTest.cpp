#include <gtest/gtest.h>

#include "core/Error.h"
#include "image/BitmapFont.h"
#include "render/ComparisonSheet.h"
#include "render/RenderTestUtil.h"
#include "demo/DemoModels.h"

namespace splatwarp {
namespace {

TEST(BitmapFontTest, GlyphsAndTextWidth)
{
    // 'L': left column and bottom row set, nothing else in the top right.
    for (int row = 0; row < kGlyphHeight; ++row) EXPECT_TRUE(glyphPixel('L', 0, row));
    for (int col = 0; col < kGlyphWidth; ++col) EXPECT_TRUE(glyphPixel('L', col, kGlyphHeight - 1));
    EXPECT_FALSE(glyphPixel('L', 4, 0));
    EXPECT_EQ(glyphPixel('a', 0, 3), glyphPixel('A', 0, 3)); // lower case drawn as upper case
    for (int row = 0; row < kGlyphHeight; ++row)
        for (int col = 0; col < kGlyphWidth; ++col) {
            EXPECT_EQ(glyphPixel('~', col, row), glyphPixel('?', col, row));
            EXPECT_FALSE(glyphPixel(' ', col, row));
        }
    EXPECT_EQ(textWidth("AB", 2), (2 * kGlyphAdvance - 1) * 2);

    Image img(20, 10, 3);
    drawText(img, -3, 2, "HI", 1, Vec3f(1, 0.5f, 0)); // clipped on the left, must not crash
    drawText(img, 0, 0, "I", 1, Vec3f(1, 1, 1));
    EXPECT_EQ(img.at(2, 3, 0), 1.0f); // middle of 'I' stem (column 2)
    EXPECT_EQ(img.at(0, 3, 0), 0.0f);
}

TEST(ComparisonSheetTest, LayoutAndCells)
{
    const GaussianCloud stripes = test::smallSample("stripes", 1500), ring = test::smallSample("ring", 1500);
    const auto cams = test::smallOrbit(stripes, 2, 40, 30);
    ComparisonSheetOptions o;
    const Image sheet = renderComparisonSheet({&stripes, &ring}, {"rest", "ring"}, cams, o);
    const int band = kGlyphHeight * o.labelScale + 2 * o.padding;
    ASSERT_EQ(sheet.width, 2 * 40 + 3 * o.padding);
    ASSERT_EQ(sheet.height, band + 2 * 30 + 2 * o.padding);
    // Cell (row 1, column 1) is exactly the direct render.
    const Image direct = renderGaussians(ring, cams[1], o.render);
    const int left = o.padding + 40 + o.padding, top = band + 30 + o.padding;
    for (int y = 0; y < 30; ++y)
        for (int x = 0; x < 40; ++x)
            for (int c = 0; c < 4; ++c) ASSERT_EQ(sheet.at(left + x, top + y, c), direct.at(x, y, c));
    // Some label pixels are drawn in the band.
    int lit = 0;
    for (int y = 0; y < band; ++y)
        for (int x = 0; x < sheet.width; ++x) lit += sheet.at(x, y, 0) == o.labelColour[0];
    EXPECT_GT(lit, 20);
    EXPECT_THROW(renderComparisonSheet({&ring}, {"a", "b"}, cams), InputError);
}

} // namespace
} // namespace splatwarp
