#include "image/ImageIO.h"

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>
#include <Imath/half.h>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <png.h>
#include <zlib.h>

#include "core/AtomicFile.h"
#include "core/Error.h"

namespace splatwarp {

std::string lowerExtension(const std::string& path)
{
    const auto dot = path.find_last_of('.');
    const auto slash = path.find_last_of('/');
    if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
    std::string ext = path.substr(dot);
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    return ext;
}

namespace {

void requireColourImage(const std::string& path, const Image& image)
{
    if (image.channels != 3 && image.channels != 4)
        throw InputError(msg(path, ": cannot write an image with ", image.channels, " channels (need 3 or 4)"));
    if (image.width <= 0 || image.height <= 0 || image.pixels.size() != image.index(0, image.height))
        throw InputError(msg(path, ": cannot write an empty or inconsistent image"));
}

std::uint8_t toByte(float v) { return std::uint8_t(std::lround(std::clamp(v, 0.0f, 1.0f) * 255.0f)); }

/// A PNG's size checked before its pixels are allocated: each side within kMaxImageSide, and pixels
/// that its bytes can hold. Deflate packs at most 1032 bytes into one (a 258-byte match costs two
/// bits or more), so a 69-byte file declaring 16000x16000 pixels (a 768 MB buffer, 1.4 s, before libpng
/// failed) is refused here.
void checkPngSize(const std::string& name, png_image& png, const unsigned char* bytes, std::size_t size)
{
    if (!imageSizeAllowed(png.width, png.height)) {
        png_image_free(&png);
        checkImageSize(name, png.width, png.height);
    }
    // libpng has read the IHDR, the first chunk: bit depth at byte 24, colour type at byte 25.
    static const int kSamples[7] = {1, 0, 3, 1, 2, 0, 4};
    const int depth = bytes[24], type = bytes[25];
    const std::uint64_t leastBits = std::uint64_t(png.width) * png.height * std::uint64_t(kSamples[type % 7]) * std::uint64_t(depth);
    constexpr std::uint64_t kDeflateMaxRatio = 1032;
    if (leastBits / 8 > std::uint64_t(size) * kDeflateMaxRatio) {
        png_image_free(&png);
        throw InputError(msg(name, ": a PNG of ", png.width, "x", png.height, " pixels cannot fit in its ", size,
                             " bytes (truncated or corrupt PNG?)"));
    }
}

/// Throws InputError naming the first pixel and channel that is not finite; `what` says what the
/// values are ("" for the file's own).
void checkFinitePixels(const std::string& path, const Image& image, const char* what)
{
    for (std::size_t i = 0; i < image.pixels.size(); ++i)
        if (!std::isfinite(image.pixels[i])) {
            const std::size_t px = i / std::size_t(image.channels);
            throw InputError(msg(path, ": pixel (", px % std::size_t(image.width), ", ", px / std::size_t(image.width),
                                 ") channel ", i % std::size_t(image.channels), " is ", image.pixels[i], what,
                                 ", not a finite value"));
        }
}

std::uint32_t bigEndian32(const unsigned char* p) { return std::uint32_t(p[0]) << 24 | p[1] << 16 | p[2] << 8 | p[3]; }

/// libpng's simplified reader takes a 16-bit PNG without gAMA, sRGB, iCCP or cHRM for linear
/// light, as the PNG spec allows, and sRGB-encodes it on the way to 8 bits: a 16-bit copy of an
/// 8-bit picture scored 13.7 dB against it. Every other tool (PIL, OpenCV, our writers' readers)
/// takes such values as they are, as for 8 bits. So such a file gets an sRGB chunk after its IHDR;
/// returns the new bytes, or "" when the file is 8-bit or says its colour space itself.
std::string withSrgbChunkIfUntagged16Bit(const unsigned char* bytes, std::size_t size)
{
    constexpr std::size_t kIhdrEnd = 8 + 8 + 13 + 4; // signature, IHDR length and type, data, CRC
    if (size < kIhdrEnd || bytes[24] != 16) return {};
    for (std::size_t at = kIhdrEnd; at + 8 <= size;) {
        const std::string type(reinterpret_cast<const char*>(bytes + at + 4), 4);
        if (type == "IDAT" || type == "IEND") break;
        if (type == "gAMA" || type == "sRGB" || type == "iCCP" || type == "cHRM") return {};
        const std::uint64_t next = std::uint64_t(at) + 12 + bigEndian32(bytes + at);
        if (next > size) break; // libpng names what is wrong
        at = std::size_t(next);
    }
    std::string chunk("\0\0\0\x01sRGB\0", 9); // length 1, type, rendering intent 0 (perceptual)
    const std::uint32_t crc = std::uint32_t(crc32(0L, reinterpret_cast<const Bytef*>(chunk.data() + 4), 5));
    for (int shift = 24; shift >= 0; shift -= 8) chunk += char((crc >> shift) & 0xff);
    std::string out(reinterpret_cast<const char*>(bytes), kIhdrEnd);
    out += chunk;
    out.append(reinterpret_cast<const char*>(bytes) + kIhdrEnd, size - kIhdrEnd);
    return out;
}

/// Float slices of R, G, B (and A) into `band`, rows from `top` on; a slice's base is addressed
/// with absolute (data window) coordinates.
Imf::FrameBuffer exrFrame(std::vector<float>& band, const Image& image, std::int64_t x0, std::int64_t top)
{
    static const char* const kNames[4] = {"R", "G", "B", "A"};
    const std::size_t xStride = sizeof(float) * std::size_t(image.channels);
    const std::size_t yStride = xStride * std::size_t(image.width);
    Imf::FrameBuffer frame;
    for (int c = 0; c < image.channels; ++c) {
        char* base = reinterpret_cast<char*>(band.data() + c) - std::ptrdiff_t(x0) * std::ptrdiff_t(xStride) -
                     std::ptrdiff_t(top) * std::ptrdiff_t(yStride);
        frame.insert(kNames[c], Imf::Slice(Imf::FLOAT, base, xStride, yStride));
    }
    return frame;
}

} // namespace

std::vector<std::uint8_t> pngBytes(const std::string& name, const Image& image, const PngWriteOptions& options)
{
    requireColourImage(name, image);
    const int out = (options.alpha && image.channels == 4) ? 4 : 3;
    std::vector<std::uint8_t> bytes(std::size_t(image.width) * image.height * out);
    for (int y = 0; y < image.height; ++y)
        for (int x = 0; x < image.width; ++x)
            for (int c = 0; c < out; ++c) {
                const float v = image.at(x, y, c);
                // Alpha is never gamma-encoded.
                const bool encode = options.values == PngValues::Linear && c < 3;
                bytes[(std::size_t(y) * image.width + x) * out + c] = toByte(encode ? linearToSrgb(v) : v);
            }
    return bytes;
}

void writePng(const std::string& path, const Image& image, const PngWriteOptions& options)
{
    const int out = (options.alpha && image.channels == 4) ? 4 : 3;
    const std::vector<std::uint8_t> bytes = pngBytes(path, image, options);
    png_image png{};
    png.version = PNG_IMAGE_VERSION;
    png.width = png_uint_32(image.width);
    png.height = png_uint_32(image.height);
    png.format = out == 4 ? PNG_FORMAT_RGBA : PNG_FORMAT_RGB;
    AtomicFile file(path);
    const int ok = png_image_write_to_file(&png, file.tempPath().c_str(), 0, bytes.data(), 0, nullptr);
    if (!ok) {
        const std::string why = png.message;
        png_image_free(&png);
        throw IoError(msg(path, ": cannot write PNG: ", why));
    }
    file.commit();
}

Image decodePng(const unsigned char* bytes, std::size_t size, const std::string& name, PngValues values)
{
    const std::string tagged = withSrgbChunkIfUntagged16Bit(bytes, size);
    if (!tagged.empty()) {
        bytes = reinterpret_cast<const unsigned char*>(tagged.data());
        size = tagged.size();
    }
    png_image png{};
    png.version = PNG_IMAGE_VERSION;
    const auto fail = [&](const char* what) {
        const std::string why = png.message;
        png_image_free(&png);
        return InputError(msg(name, ": ", what, ": ", why));
    };
    if (!png_image_begin_read_from_memory(&png, bytes, size)) throw fail("cannot read PNG");
    checkPngSize(name, png, bytes, size);
    const bool alpha = (png.format & PNG_FORMAT_FLAG_ALPHA) != 0;
    // 8-bit sRGB output: libpng converts grey, palette and 16-bit files to it.
    png.format = alpha ? PNG_FORMAT_RGBA : PNG_FORMAT_RGB;
    const int channels = alpha ? 4 : 3;
    std::vector<std::uint8_t> data(PNG_IMAGE_SIZE(png));
    if (!png_image_finish_read(&png, nullptr, data.data(), 0, nullptr)) throw fail("corrupt PNG");
    Image image(int(png.width), int(png.height), channels);
    for (std::size_t i = 0; i < image.pixels.size(); ++i) {
        const float v = float(data[i]) / 255.0f;
        const bool decode = values == PngValues::Linear && int(i % std::size_t(channels)) < 3;
        image.pixels[i] = decode ? srgbToLinear(v) : v;
    }
    return image;
}

Image readPng(const std::string& path, PngValues values)
{
    const std::string bytes = readWholeFile(path);
    return decodePng(reinterpret_cast<const unsigned char*>(bytes.data()), bytes.size(), path, values);
}

void writeExr(const std::string& path, const Image& image, ExrPixelType type)
{
    requireColourImage(path, image);
    static const char* const kNames[4] = {"R", "G", "B", "A"};
    const Imf::PixelType pixelType = type == ExrPixelType::Half ? Imf::HALF : Imf::FLOAT;
    Imf::Header header(image.width, image.height);
    header.compression() = Imf::ZIP_COMPRESSION;
    for (int c = 0; c < image.channels; ++c) header.channels().insert(kNames[c], Imf::Channel(pixelType));
    // Half data needs its own buffer; float data is sliced straight out of the image.
    std::vector<Imath::half> halves;
    if (type == ExrPixelType::Half) halves.assign(image.pixels.begin(), image.pixels.end());
    Imf::FrameBuffer frame;
    const std::size_t xStride = std::size_t(image.channels), yStride = xStride * std::size_t(image.width);
    for (int c = 0; c < image.channels; ++c) {
        char* base = type == ExrPixelType::Half ? reinterpret_cast<char*>(halves.data() + c)
                                                : reinterpret_cast<char*>(const_cast<float*>(image.pixels.data() + c));
        const std::size_t bytes = type == ExrPixelType::Half ? sizeof(Imath::half) : sizeof(float);
        frame.insert(kNames[c], Imf::Slice(pixelType, base, xStride * bytes, yStride * bytes));
    }
    AtomicFile file(path);
    try {
        Imf::OutputFile out(file.tempPath().c_str(), header);
        out.setFrameBuffer(frame);
        out.writePixels(image.height);
    } catch (const std::exception& e) {
        throw IoError(msg(path, ": cannot write EXR: ", e.what()));
    }
    file.commit();
}

Image readExr(const std::string& path)
{
    try {
        Imf::InputFile in(path.c_str());
        const Imath::Box2i dw = in.header().dataWindow();
        const std::int64_t x0 = dw.min.x, y0 = dw.min.y;
        checkImageSize(path, std::int64_t(dw.max.x) - x0 + 1, std::int64_t(dw.max.y) - y0 + 1);
        const Imf::ChannelList& list = in.header().channels();
        for (const char* name : {"R", "G", "B"})
            if (!list.findChannel(name)) throw InputError(msg(path, ": EXR has no '", name, "' channel"));
        Image image;
        image.width = dw.max.x - dw.min.x + 1;
        image.height = dw.max.y - dw.min.y + 1;
        image.channels = list.findChannel("A") != nullptr ? 4 : 3;
        // Read in bands, the image growing with them: a data window forged larger than the file's
        // pixels (OpenEXR checks only its offset table first) fails at its first missing band, not
        // after allocating the whole picture (an 11 KB file cost 6.3 GB).
        constexpr std::int64_t kBand = 256;
        std::vector<float> band;
        for (std::int64_t top = y0; top <= dw.max.y; top += kBand) {
            const std::int64_t bottom = std::min<std::int64_t>(dw.max.y, top + kBand - 1);
            band.assign(std::size_t(bottom - top + 1) * std::size_t(image.width) * std::size_t(image.channels), 0.0f);
            in.setFrameBuffer(exrFrame(band, image, x0, top));
            in.readPixels(int(top), int(bottom));
            image.pixels.insert(image.pixels.end(), band.begin(), band.end());
        }
        // A NaN scores as nothing (compare printed "PSNR nan" and exit 0): refused, named.
        checkFinitePixels(path, image, "");
        return image;
    } catch (const Error&) {
        throw;
    } catch (const std::exception& e) {
        throw IoError(msg(path, ": cannot read EXR: ", e.what()));
    }
}

bool isImagePath(const std::string& path)
{
    const std::string ext = lowerExtension(path);
    return ext == ".png" || ext == ".exr";
}

void writeImage(const std::string& path, const Image& image)
{
    const std::string ext = lowerExtension(path);
    if (ext == ".png")
        writePng(path, image);
    else if (ext == ".exr") {
        const Image linear = displayToLinear(image);
        // Display values past ~1.4e16 (a splat colour of 1e20) have no finite linear value: compare refused the file.
        checkFinitePixels(path, linear, " when decoded to linear light; refusing to write it");
        writeExr(path, linear);
    }
    else
        throw InputError(msg(path, ": unknown image extension (use .png or .exr)"));
}

Image readImage(const std::string& path)
{
    const std::string ext = lowerExtension(path);
    if (ext == ".png") return readPng(path);
    if (ext == ".exr") {
        Image display = linearToDisplay(readExr(path));
        // Linear values below about -2.6e37 overflow the sRGB encoding: compare called such files identical.
        checkFinitePixels(path, display, " when sRGB-encoded");
        return display;
    }
    throw InputError(msg(path, ": unknown image extension (use .png or .exr)"));
}

} // namespace splatwarp
