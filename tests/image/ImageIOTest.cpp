#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <random>

#include "core/AtomicFile.h"
#include "core/Error.h"
#include "image/ImageIO.h"
#include "image/ImageTestUtil.h"
#include "support/TestSupport.h"

namespace splatwarp {
namespace {

using test::randomImage;

TEST(ImageIOTest, SrgbCurveRoundTripsAndMatchesKnownPoints)
{
    EXPECT_FLOAT_EQ(linearToSrgb(0.0f), 0.0f);
    EXPECT_FLOAT_EQ(linearToSrgb(1.0f), 1.0f);
    EXPECT_NEAR(linearToSrgb(0.18f), 0.4613561, 1e-6); // 1.055 * 0.18^(1/2.4) - 0.055
    for (float v = 0.0f; v <= 1.0f; v += 0.01f) EXPECT_NEAR(srgbToLinear(linearToSrgb(v)), v, 1e-6);
}

TEST(ImageIOTest, PngRoundTrip)
{
    test::TempDir dir;
    // Display values (the default): exact 8-bit levels survive unchanged.
    Image levels(7, 5, 4);
    for (std::size_t i = 0; i < levels.pixels.size(); ++i) levels.pixels[i] = float(i * 37 % 256) / 255.0f;
    PngWriteOptions raw;
    raw.alpha = true;
    writePng(dir.file("levels.png"), levels, raw);
    const Image back = readPng(dir.file("levels.png"));
    ASSERT_EQ(back.width, 7);
    ASSERT_EQ(back.height, 5);
    ASSERT_EQ(back.channels, 4);
    EXPECT_TRUE(back.pixels == levels.pixels);

    // Linear values: encode, quantise, decode. Error bounded by half an 8-bit step in sRGB space.
    const Image lin = randomImage(9, 6, 4, 3);
    PngWriteOptions linear;
    linear.values = PngValues::Linear;
    writePng(dir.file("lin.png"), lin, linear);
    const Image rgb = readPng(dir.file("lin.png"), PngValues::Linear);
    ASSERT_EQ(rgb.channels, 3); // alpha dropped by default
    for (int y = 0; y < 6; ++y)
        for (int x = 0; x < 9; ++x)
            for (int c = 0; c < 3; ++c) {
                const float expected = srgbToLinear(std::round(linearToSrgb(lin.at(x, y, c)) * 255.0f) / 255.0f);
                EXPECT_NEAR(rgb.at(x, y, c), expected, 1e-6);
                EXPECT_NEAR(linearToSrgb(rgb.at(x, y, c)), linearToSrgb(lin.at(x, y, c)), 0.5 / 255 + 1e-6);
            }
}

TEST(ImageIOTest, ExrRoundTripKeepsValuesAndAlpha)
{
    test::TempDir dir;
    Image img = randomImage(13, 7, 4, 5);
    img.at(0, 0, 0) = 3.5f; // HDR values are allowed in EXR
    writeExr(dir.file("f.exr"), img, ExrPixelType::Float);
    const Image f = readExr(dir.file("f.exr"));
    ASSERT_EQ(f.channels, 4);
    ASSERT_EQ(f.width, 13);
    EXPECT_TRUE(f.pixels == img.pixels);

    writeExr(dir.file("h.exr"), img); // half by default
    const Image h = readExr(dir.file("h.exr"));
    ASSERT_EQ(h.channels, 4);
    for (std::size_t i = 0; i < img.pixels.size(); ++i)
        EXPECT_NEAR(h.pixels[i], img.pixels[i], std::abs(img.pixels[i]) * (1.0 / 2048) + 1e-7); // half: 11-bit mantissa

    Image rgb = randomImage(4, 3, 3, 9);
    writeExr(dir.file("rgb.exr"), rgb, ExrPixelType::Float);
    EXPECT_EQ(readExr(dir.file("rgb.exr")).channels, 3);
}

// The stripes red band: a display value of (224, 52, 40) / 255 is stored as those bytes in
// a PNG (as graphdeco's renderer and PlayCanvas show it; the old linear -> sRGB encoding wrote
// (241, 125, 111)), and as its linear decode in an EXR, which readImage() encodes back.
TEST(ImageIOTest, RenderValuesAreDisplayValuesPngAsIsExrLinear)
{
    test::TempDir dir;
    Image red(2, 1, 4, 1.0f);
    const float bytes[3] = {224, 52, 40};
    for (int x = 0; x < 2; ++x)
        for (int c = 0; c < 3; ++c) red.at(x, 0, c) = bytes[c] / 255.0f;
    writeImage(dir.file("red.png"), red);
    const Image png = readPng(dir.file("red.png"));
    for (int c = 0; c < 3; ++c) EXPECT_EQ(std::lround(png.at(1, 0, c) * 255.0f), std::lround(bytes[c])) << c;
    writeExr(dir.file("red.exr"), displayToLinear(red), ExrPixelType::Float);
    writeImage(dir.file("half.exr"), red);
    const Image lin = readExr(dir.file("red.exr"));
    EXPECT_NEAR(lin.at(0, 0, 0), std::pow((224.0 / 255 + 0.055) / 1.055, 2.4), 1e-6); // 0.7454
    EXPECT_NEAR(lin.at(0, 0, 2), std::pow((40.0 / 255 + 0.055) / 1.055, 2.4), 1e-6);  // 0.0212
    EXPECT_FLOAT_EQ(lin.at(0, 0, 3), 1.0f);                                            // alpha as is
    const Image back = readImage(dir.file("half.exr"));
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(back.at(0, 0, c), bytes[c] / 255.0f, 1e-3) << c;
    // Out-of-range values (SH can exceed 1) survive the EXR round trip.
    Image bright(1, 1, 3, 1.25f);
    EXPECT_NEAR(linearToDisplay(displayToLinear(bright)).pixels[0], 1.25f, 1e-5);
}

TEST(ImageIOTest, ErrorsNameTheFileAndLeaveNothingBehind)
{
    test::TempDir dir;
    const Image img(4, 4, 3, 0.5f);
    EXPECT_THROW(writeImage(dir.file("x.jpg"), img), InputError);
    EXPECT_THROW(writePng(dir.file("x.png"), Image(4, 4, 2)), InputError);
    EXPECT_THROW(writePng(dir.file("nodir/x.png"), img), IoError);
    EXPECT_THROW(writeExr(dir.file("nodir/x.exr"), img), IoError);
    EXPECT_THROW(readPng(dir.file("missing.png")), IoError);
    writeFileAtomic(dir.file("text.png"), "not a png");
    try {
        readPng(dir.file("text.png"));
        FAIL() << "expected an error";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("text.png"), std::string::npos);
    }
    EXPECT_THROW(readExr(dir.file("text.png")), IoError);
    // Only the text file: no temporaries, no partial outputs.
    int files = 0;
    for (const auto& entry : std::filesystem::directory_iterator(dir.path())) {
        (void)entry;
        ++files;
    }
    EXPECT_EQ(files, 1);
    EXPECT_TRUE(isImagePath("a/B.PNG"));
    EXPECT_FALSE(isImagePath("a.png/b"));
}

} // namespace
} // namespace splatwarp
