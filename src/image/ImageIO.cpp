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

#include "core/AtomicFile.h"
#include "core/Error.h"

namespace splatwarp {

namespace {

std::string lowerExtension(const std::string& path)
{
    const auto dot = path.find_last_of('.');
    const auto slash = path.find_last_of('/');
    if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
    std::string ext = path.substr(dot);
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    return ext;
}

void requireColourImage(const std::string& path, const Image& image)
{
    if (image.channels != 3 && image.channels != 4)
        throw InputError(msg(path, ": cannot write an image with ", image.channels, " channels (need 3 or 4)"));
    if (image.width <= 0 || image.height <= 0 || image.pixels.size() != image.index(0, image.height))
        throw InputError(msg(path, ": cannot write an empty or inconsistent image"));
}

std::uint8_t toByte(float v) { return std::uint8_t(std::lround(std::clamp(v, 0.0f, 1.0f) * 255.0f)); }

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

Image readPng(const std::string& path, PngValues values)
{
    png_image png{};
    png.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_file(&png, path.c_str())) {
        const std::string why = png.message;
        png_image_free(&png);
        throw IoError(msg(path, ": cannot read PNG: ", why));
    }
    const bool alpha = (png.format & PNG_FORMAT_FLAG_ALPHA) != 0;
    // 8-bit sRGB output: libpng converts grey, palette and 16-bit files to it.
    png.format = alpha ? PNG_FORMAT_RGBA : PNG_FORMAT_RGB;
    const int channels = alpha ? 4 : 3;
    std::vector<std::uint8_t> bytes(PNG_IMAGE_SIZE(png));
    if (!png_image_finish_read(&png, nullptr, bytes.data(), 0, nullptr)) {
        const std::string why = png.message;
        png_image_free(&png);
        throw InputError(msg(path, ": corrupt PNG: ", why));
    }
    Image image(int(png.width), int(png.height), channels);
    for (std::size_t i = 0; i < image.pixels.size(); ++i) {
        const float v = float(bytes[i]) / 255.0f;
        const bool decode = values == PngValues::Linear && int(i % std::size_t(channels)) < 3;
        image.pixels[i] = decode ? srgbToLinear(v) : v;
    }
    return image;
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
        const int width = dw.max.x - dw.min.x + 1, height = dw.max.y - dw.min.y + 1;
        const Imf::ChannelList& list = in.header().channels();
        for (const char* name : {"R", "G", "B"})
            if (!list.findChannel(name)) throw InputError(msg(path, ": EXR has no '", name, "' channel"));
        const bool alpha = list.findChannel("A") != nullptr;
        Image image(width, height, alpha ? 4 : 3);
        const std::size_t xStride = sizeof(float) * std::size_t(image.channels);
        const std::size_t yStride = xStride * std::size_t(width);
        static const char* const kNames[4] = {"R", "G", "B", "A"};
        Imf::FrameBuffer frame;
        for (int c = 0; c < image.channels; ++c) {
            // The slice base is addressed with absolute (data window) coordinates.
            char* base = reinterpret_cast<char*>(image.pixels.data() + c) - std::ptrdiff_t(dw.min.x) * std::ptrdiff_t(xStride) -
                         std::ptrdiff_t(dw.min.y) * std::ptrdiff_t(yStride);
            frame.insert(kNames[c], Imf::Slice(Imf::FLOAT, base, xStride, yStride));
        }
        in.setFrameBuffer(frame);
        in.readPixels(dw.min.y, dw.max.y);
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
    else if (ext == ".exr")
        writeExr(path, displayToLinear(image));
    else
        throw InputError(msg(path, ": unknown image extension (use .png or .exr)"));
}

Image readImage(const std::string& path)
{
    const std::string ext = lowerExtension(path);
    if (ext == ".png") return readPng(path);
    if (ext == ".exr") return linearToDisplay(readExr(path));
    throw InputError(msg(path, ": unknown image extension (use .png or .exr)"));
}

} // namespace splatwarp
