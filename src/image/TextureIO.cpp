#include "image/TextureIO.h"

#include <csetjmp>
#include <cstdio>
#include <jpeglib.h>
#include <jerror.h>
#include <png.h>
#include <vector>

#include "core/AtomicFile.h"
#include "core/Error.h"
#include "image/ImageIO.h"

namespace splatwarp {

namespace {

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

/// A file cut short is only a warning to libjpeg (JWRN_JPEG_EOF, or JWRN_HIT_MARKER where a marker
/// such as the end of image comes before the picture's data does: it fills the rest of the picture
/// with grey); a texture or a training picture cut in half is a corrupt input, so it is an error.
void jpegMessage(j_common_ptr info, int level)
{
    const int code = info->err->msg_code;
    if (level < 0 && (code == JWRN_JPEG_EOF || code == JWRN_HIT_MARKER)) jpegErrorExit(info);
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
    if (!imageSizeAllowed(info.image_width, info.image_height)) {
        jpeg_destroy_decompress(&info);
        checkImageSize(name, info.image_width, info.image_height);
    }
    info.out_color_space = JCS_RGB; // greyscale and YCbCr files alike
    jpeg_start_decompress(&info);
    width = int(info.output_width);
    height = int(info.output_height);
    // The pixels grow with the rows decoded: a header forged larger than the file's data fails at
    // its first missing row (JWRN_JPEG_EOF), not after allocating the whole picture (a 631-byte file
    // declaring 65000x65000 pixels cost 12 GB).
    const std::size_t rowBytes = std::size_t(width) * 3;
    while (info.output_scanline < info.output_height) {
        data.resize(data.size() + rowBytes);
        JSAMPROW row = data.data() + data.size() - rowBytes;
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
    switch (pictureFormat(bytes, size)) {
    case PictureFormat::Png: return decodePng(bytes, size, name, PngValues::Display);
    case PictureFormat::Jpeg: return decodeJpeg(bytes, size, name);
    case PictureFormat::Other: break;
    }
    throw InputError(msg(name, ": not a PNG or JPEG image"));
}

Image readTexture(const std::string& path)
{
    const std::string bytes = readWholeFile(path, "picture");
    return decodeTexture(reinterpret_cast<const unsigned char*>(bytes.data()), bytes.size(), path);
}

} // namespace splatwarp
