#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
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

/// CRC-32 of PNG chunks (ISO 3309), for forging a header that libpng accepts.
std::uint32_t pngCrc(const std::string& bytes)
{
    std::uint32_t c = 0xFFFFFFFFu;
    for (unsigned char b : bytes) {
        c ^= b;
        for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0xEDB88320u & (0u - (c & 1u)));
    }
    return c ^ 0xFFFFFFFFu;
}

void putBig32(std::string& s, std::size_t at, std::uint32_t v)
{
    for (int i = 0; i < 4; ++i) s[at + std::size_t(i)] = char((v >> (24 - 8 * i)) & 0xFF);
}

/// A small PNG whose IHDR declares width x height (its CRC recomputed), the pixels still 8x8.
std::string pngDeclaring(const std::string& small, std::uint32_t width, std::uint32_t height)
{
    std::string s = small;
    putBig32(s, 16, width);
    putBig32(s, 20, height);
    putBig32(s, 29, pngCrc(s.substr(12, 17)));
    return s;
}

/// A small scan-line EXR whose data window declares side x side pixels, with an offset table of
/// that many chunks all pointing at its one real chunk: what OpenEXR checks before the pixels.
std::string exrDeclaring(const std::string& small, int side)
{
    std::string s = small;
    for (const std::string name : {"dataWindow", "displayWindow"}) {
        const std::size_t at = s.find(name + std::string("\0box2i\0", 7)) + name.size() + 7 + 4;
        const std::int32_t box[4] = {0, 0, side - 1, side - 1};
        std::memcpy(&s[at], box, sizeof(box));
    }
    std::size_t table = 8;
    for (; table + 16 <= s.size(); ++table) { // the one offset points just past itself
        std::uint64_t v = 0;
        std::memcpy(&v, &s[table], 8);
        if (v == table + 8) break;
    }
    const std::size_t chunks = std::size_t(side + 15) / 16; // ZIP: 16 lines a chunk
    const std::uint64_t offset = table + 8 * chunks;
    std::string out = s.substr(0, table);
    for (std::size_t i = 0; i < chunks; ++i) out.append(reinterpret_cast<const char*>(&offset), 8);
    return out + s.substr(table + 8);
}

TEST(ImageIOTest, SrgbCurveRoundTripsAndMatchesKnownPoints)
{
    EXPECT_FLOAT_EQ(linearToSrgb(0.0f), 0.0f);
    EXPECT_FLOAT_EQ(linearToSrgb(1.0f), 1.0f);
    EXPECT_NEAR(linearToSrgb(0.18f), 0.4613561, 1e-6); // 1.055 * 0.18^(1/2.4) - 0.055
    for (float v = 0.0f; v <= 1.0f; v += 0.01f) EXPECT_NEAR(srgbToLinear(linearToSrgb(v)), v, 1e-6);
}

/// A 16-bit RGB PNG of `samples` (row-major, 3 per pixel), stored (uncompressed) deflate, with the
/// chunk `extra` (type + data, e.g. "sRGB\0") after the IHDR when given: what libpng's writer
/// cannot make (it tags 16-bit output as linear).
std::string png16(int width, int height, const std::vector<std::uint16_t>& samples, const std::string& extra = "")
{
    const auto chunk = [](const std::string& typeAndData) {
        std::string c(4, '\0');
        putBig32(c, 0, std::uint32_t(typeAndData.size() - 4));
        std::string crc(4, '\0');
        putBig32(crc, 0, pngCrc(typeAndData));
        return c + typeAndData + crc;
    };
    std::string ihdr = "IHDR" + std::string(13, '\0');
    putBig32(ihdr, 4, std::uint32_t(width));
    putBig32(ihdr, 8, std::uint32_t(height));
    ihdr[12] = 16; // bit depth
    ihdr[13] = 2;  // RGB
    std::string raw;
    for (int y = 0; y < height; ++y) {
        raw += '\0'; // filter: none
        for (int x = 0; x < 3 * width; ++x) {
            const std::uint16_t v = samples[std::size_t(y) * std::size_t(3 * width) + std::size_t(x)];
            raw += char(v >> 8);
            raw += char(v & 0xFF);
        }
    }
    std::string z = "\x78\x01\x01"; // zlib header, one final stored block (raw < 65536)
    z += char(raw.size() & 0xFF);
    z += char(raw.size() >> 8);
    z += char(~raw.size() & 0xFF);
    z += char((~raw.size() >> 8) & 0xFF);
    z += raw;
    std::uint32_t a = 1, b = 0; // Adler-32
    for (unsigned char c : raw) {
        a = (a + c) % 65521;
        b = (b + a) % 65521;
    }
    std::string adler(4, '\0');
    putBig32(adler, 0, (b << 16) | a);
    z += adler;
    return "\x89PNG\r\n\x1a\n" + chunk(ihdr) + (extra.empty() ? "" : chunk(extra)) + chunk("IDAT" + z) + chunk("IEND");
}

// libpng took 16-bit PNGs without a colour space for linear light and sRGB-encoded them: an exact
// 16-bit copy of an 8-bit picture scored 13.7 dB against it.
TEST(ImageIOTest, SixteenBitPngsReadAsTheirValuesUnlessTheySayOtherwise)
{
    test::TempDir dir;
    const int w = 5, h = 3;
    Image levels(w, h, 3);
    std::vector<std::uint16_t> wide;
    for (std::size_t i = 0; i < levels.pixels.size(); ++i) {
        const unsigned v = unsigned(i * 53 % 256);
        levels.pixels[i] = float(v) / 255.0f;
        wide.push_back(std::uint16_t(v * 257));
    }
    writePng(dir.file("eight.png"), levels);
    EXPECT_TRUE(readPng(dir.file("eight.png")).pixels == levels.pixels);
    writeFileAtomic(dir.file("untagged16.png"), png16(w, h, wide));
    writeFileAtomic(dir.file("srgb16.png"), png16(w, h, wide, std::string("sRGB\0", 5)));
    EXPECT_TRUE(readPng(dir.file("untagged16.png")).pixels == levels.pixels);
    EXPECT_TRUE(readPng(dir.file("srgb16.png")).pixels == levels.pixels);
    // A file that says it is linear (gAMA 1.0) is still sRGB-encoded on the way in.
    std::string gamma1 = std::string("gAMA") + std::string(4, '\0');
    putBig32(gamma1, 4, 100000);
    writeFileAtomic(dir.file("linear16.png"), png16(w, h, wide, gamma1));
    const Image linear = readPng(dir.file("linear16.png"));
    EXPECT_FALSE(linear.pixels == levels.pixels);
    EXPECT_NEAR(linear.pixels[3], linearToSrgb(levels.pixels[3]), 1.0 / 255);
}

// Display values without a finite linear one (render of a colour of 1e20) made an EXR of inf that
// compare refused; linear values below -2.6e37 overflowed the sRGB encoding and compare called
// such a file identical to any other.
TEST(ImageIOTest, ExrValuesBeyondTheEncodingAreRefused)
{
    test::TempDir dir;
    Image hot(4, 4, 3, 0.5f);
    hot.at(1, 2, 0) = 1e20f;
    EXPECT_THROW(writeImage(dir.file("hot.exr"), hot), InputError);
    EXPECT_FALSE(std::filesystem::exists(dir.file("hot.exr")));
    Image cold(4, 4, 3, 0.0f);
    cold.at(3, 1, 2) = -1e38f;
    writeExr(dir.file("cold.exr"), cold, ExrPixelType::Float);
    try {
        readImage(dir.file("cold.exr"));
        ADD_FAILURE() << "accepted";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("pixel (3, 1) channel 2"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("when sRGB-encoded"), std::string::npos) << e.what();
    }
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

    // A NaN or an infinity is no value to compare or train on: refused, naming the pixel.
    img.at(5, 2, 1) = std::nanf("");
    writeExr(dir.file("nan.exr"), img, ExrPixelType::Float);
    const std::string m = test::inputErrorMessage([&] { readExr(dir.file("nan.exr")); });
    EXPECT_NE(m.find("nan.exr: pixel (5, 2) channel 1"), std::string::npos) << m;
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

// A header that declares more pixels than the file holds is refused before the pixels are
// allocated (a 69-byte PNG cost 2 GB, an 11 KB EXR 6.3 GB): past kMaxImageSide by its size,
// below it by what the bytes can hold (PNG) or at the first band that is not there (EXR).
TEST(ImageIOTest, ForgedSizesAreRefusedBeforeTheirPixels)
{
    test::TempDir dir;
    writePng(dir.file("small.png"), randomImage(8, 8, 3, 1));
    const std::string png = test::fileBytes(dir.file("small.png"));
    writeFileAtomic(dir.file("huge.png"), pngDeclaring(png, 60000, 60000));
    std::string e = test::inputErrorMessage([&] { readPng(dir.file("huge.png")); });
    EXPECT_NE(e.find("huge.png: an image of 60000x60000 pixels: each side must be from 1 to 16384 (downscale"), std::string::npos) << e;
    writeFileAtomic(dir.file("big.png"), pngDeclaring(png, 16000, 16000));
    e = test::inputErrorMessage([&] { readPng(dir.file("big.png")); });
    EXPECT_NE(e.find("big.png: a PNG of 16000x16000 pixels cannot fit in its"), std::string::npos) << e;
    // Near deflate's limit (1032 bytes in one), a whole black picture still reads.
    writePng(dir.file("black.png"), Image(2048, 2048, 3, 0.0f));
    EXPECT_EQ(readPng(dir.file("black.png")).width, 2048);

    writeExr(dir.file("small.exr"), randomImage(16, 16, 3, 2));
    const std::string exr = test::fileBytes(dir.file("small.exr"));
    writeFileAtomic(dir.file("huge.exr"), exrDeclaring(exr, 20001));
    e = test::inputErrorMessage([&] { readExr(dir.file("huge.exr")); });
    EXPECT_NE(e.find("huge.exr: an image of 20001x20001 pixels"), std::string::npos) << e;
    writeFileAtomic(dir.file("big.exr"), exrDeclaring(exr, 16000));
    EXPECT_THROW(readExr(dir.file("big.exr")), IoError);
    // The forging keeps a file readable: at its own size it reads back.
    writeFileAtomic(dir.file("same.exr"), exrDeclaring(exr, 16));
    EXPECT_EQ(readExr(dir.file("same.exr")).pixels, readExr(dir.file("small.exr")).pixels);
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
