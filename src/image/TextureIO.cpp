#include "image/TextureIO.h"

#include <csetjmp>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <jpeglib.h>
#include <jerror.h>
#include <png.h>
#include <vector>

#include "core/Error.h"

namespace splatwarp {

namespace {

Image decodePng(const unsigned char* bytes, std::size_t size, const std::string& name)
{
    png_image png{};
    png.version = PNG_IMAGE_VERSION;
    const auto fail = [&](const char* what) {
        const std::string why = png.message;
        png_image_free(&png);
        return InputError(msg(name, ": ", what, ": ", why));
    };
    if (!png_image_begin_read_from_memory(&png, bytes, size)) throw fail("cannot read PNG");
    const bool alpha = (png.format & PNG_FORMAT_FLAG_ALPHA) != 0;
    png.format = alpha ? PNG_FORMAT_RGBA : PNG_FORMAT_RGB;
    std::vector<std::uint8_t> data(PNG_IMAGE_SIZE(png));
    if (!png_image_finish_read(&png, nullptr, data.data(), 0, nullptr)) throw fail("corrupt PNG");
    Image image(int(png.width), int(png.height), alpha ? 4 : 3);
    for (std::size_t i = 0; i < image.pixels.size(); ++i) image.pixels[i] = float(data[i]) / 255.0f;
    return image;
}

/// libjpeg reports errors through a callback that must not return: jump back to the decoder.
struct JpegError {
    jpeg_error_mgr base;
    std::jmp_buf jump;
    char text[JMSG_LENGTH_MAX];
    void (*emit)(j_common_ptr, int) = nullptr; ///< libjpeg's own, for every other message
};

void jpegErrorExit(j_common_ptr info)
{
    auto* e = reinterpret_cast<JpegError*>(info->err);
    (*info->err->format_message)(info, e->text);
    std::longjmp(e->jump, 1);
}

/// A file cut short is only a warning to libjpeg (JWRN_JPEG_EOF: it fills the rest of the picture
/// with grey); a texture or a training picture cut in half is a corrupt input, so it is an error.
void jpegMessage(j_common_ptr info, int level)
{
    if (level < 0 && info->err->msg_code == JWRN_JPEG_EOF) jpegErrorExit(info);
    (*reinterpret_cast<JpegError*>(info->err)->emit)(info, level);
}

Image decodeJpeg(const unsigned char* bytes, std::size_t size, const std::string& name)
{
    jpeg_decompress_struct info{};
    JpegError err{};
    info.err = jpeg_std_error(&err.base);
    err.base.error_exit = jpegErrorExit;
    err.emit = err.base.emit_message;
    err.base.emit_message = jpegMessage;
    // Only plain data lives across the jump: the image is allocated after the header is read.
    std::vector<std::uint8_t> data;
    int width = 0, height = 0;
    if (setjmp(err.jump)) {
        jpeg_destroy_decompress(&info);
        throw InputError(msg(name, ": corrupt JPEG: ", err.text));
    }
    jpeg_create_decompress(&info);
    jpeg_mem_src(&info, bytes, static_cast<unsigned long>(size));
    jpeg_read_header(&info, TRUE);
    info.out_color_space = JCS_RGB; // greyscale and YCbCr files alike
    jpeg_start_decompress(&info);
    width = int(info.output_width);
    height = int(info.output_height);
    data.resize(std::size_t(width) * std::size_t(height) * 3);
    while (info.output_scanline < info.output_height) {
        JSAMPROW row = data.data() + std::size_t(info.output_scanline) * std::size_t(width) * 3;
        jpeg_read_scanlines(&info, &row, 1);
    }
    jpeg_finish_decompress(&info);
    jpeg_destroy_decompress(&info);
    Image image(width, height, 3);
    for (std::size_t i = 0; i < image.pixels.size(); ++i) image.pixels[i] = float(data[i]) / 255.0f;
    return image;
}

} // namespace

Image decodeTexture(const unsigned char* bytes, std::size_t size, const std::string& name)
{
    static const unsigned char kPng[4] = {0x89, 'P', 'N', 'G'};
    if (size >= 4 && std::equal(kPng, kPng + 4, bytes)) return decodePng(bytes, size, name);
    if (size >= 3 && bytes[0] == 0xFF && bytes[1] == 0xD8 && bytes[2] == 0xFF) return decodeJpeg(bytes, size, name);
    throw InputError(msg(name, ": not a PNG or JPEG image"));
}

Image readTexture(const std::string& path)
{
    std::ifstream in(path, std::ios::binary);
    if (!in) throw IoError(msg(path, ": cannot open texture"));
    const std::vector<unsigned char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    return decodeTexture(bytes.data(), bytes.size(), path);
}

} // namespace splatwarp
