#include "image/PictureSize.h"

#include <algorithm>
#include <memory>

#include "core/Camera.h"
#include "core/Error.h"

namespace splatwarp {

bool imageSizeAllowed(std::int64_t width, std::int64_t height)
{
    return width >= 1 && height >= 1 && width <= kMaxImageSide && height <= kMaxImageSide;
}

void checkImageSize(const std::string& name, std::int64_t width, std::int64_t height)
{
    if (!imageSizeAllowed(width, height))
        throw InputError(msg(name, ": an image of ", width, "x", height, " pixels: each side must be from 1 to ",
                             kMaxImageSide, " (downscale a larger picture first; or the file is corrupt)"));
}

PictureFormat pictureFormat(const unsigned char* bytes, std::size_t size)
{
    static const unsigned char kPng[4] = {0x89, 'P', 'N', 'G'};
    if (size >= 4 && std::equal(kPng, kPng + 4, bytes)) return PictureFormat::Png;
    if (size >= 3 && bytes[0] == 0xFF && bytes[1] == 0xD8 && bytes[2] == 0xFF) return PictureFormat::Jpeg;
    return PictureFormat::Other;
}

namespace {

/// The frame header's size of a JPEG file: its segments walked from the start of image to the
/// first SOF marker (C0-CF but C4 DHT, C8 JPG, CC DAC), each skipped by its length.
PictureSize jpegSize(std::FILE* f, const std::string& path)
{
    const auto byte = [&] {
        const int c = std::fgetc(f);
        if (c == EOF) throw InputError(msg(path, ": corrupt JPEG: the file ends before its frame header"));
        return c;
    };
    for (;;) {
        int marker = byte();
        if (marker != 0xFF) throw InputError(msg(path, ": corrupt JPEG: a segment does not start with a marker"));
        while (marker == 0xFF) marker = byte(); // fill bytes
        if (marker == 0xD8 || (marker >= 0xD0 && marker <= 0xD7) || marker == 0x01) continue; // no length
        const int length = (byte() << 8) | byte();
        if (length < 2) throw InputError(msg(path, ": corrupt JPEG: a segment of length ", length));
        const bool frame = marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 && marker != 0xCC;
        if (frame) {
            byte(); // sample precision
            const int height = (byte() << 8) | byte();
            const int width = (byte() << 8) | byte();
            checkImageSize(path, width, height);
            return {width, height};
        }
        if (marker == 0xDA || marker == 0xD9) throw InputError(msg(path, ": corrupt JPEG: no frame header before its data"));
        if (std::fseek(f, long(length - 2), SEEK_CUR) != 0) throw InputError(msg(path, ": corrupt JPEG: cannot skip a segment"));
    }
}

} // namespace

PictureSize pictureSize(std::FILE* f, const std::string& path)
{
    unsigned char head[24] = {};
    const std::size_t got = std::fread(head, 1, sizeof(head), f);
    const PictureFormat format = pictureFormat(head, got);
    if (format == PictureFormat::Png) {
        // The IHDR chunk comes first: its width and height are bytes 16-23, big-endian.
        if (got < 24 || !std::equal(head + 12, head + 16, "IHDR")) throw InputError(msg(path, ": corrupt PNG: no IHDR chunk first"));
        const auto be32 = [&](int at) {
            return (std::int64_t(head[at]) << 24) | (std::int64_t(head[at + 1]) << 16) | (std::int64_t(head[at + 2]) << 8) | head[at + 3];
        };
        checkImageSize(path, be32(16), be32(20));
        return {int(be32(16)), int(be32(20))};
    }
    if (format == PictureFormat::Jpeg) {
        if (std::fseek(f, 2, SEEK_SET) != 0) throw InputError(msg(path, ": corrupt JPEG: cannot read its segments"));
        return jpegSize(f, path);
    }
    throw InputError(msg(path, ": not a PNG or JPEG image"));
}

PictureSize readTextureSize(const std::string& path)
{
    std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(path.c_str(), "rb"), &std::fclose);
    if (!f) throw IoError(msg(path, ": cannot open the picture"));
    return pictureSize(f.get(), path);
}

} // namespace splatwarp
