#pragma once
/// @file PictureSize.h
/// @brief A picture's size: the limit every image reader checks before allocating pixels, and a
///        PNG's or JPEG's size read from its header alone (no pixel decoded).
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>

namespace splatwarp {

/// @brief A picture's width and height.
struct PictureSize {
    int width = 0, height = 0;
};

/// @brief True when each side is in [1, kMaxImageSide] (core/Camera.h: the largest picture a
///        camera file or --size may ask for). Every image reader checks a file's declared size so
///        before allocating its pixels.
bool imageSizeAllowed(std::int64_t width, std::int64_t height);
/// @brief Throws InputError naming `name` unless imageSizeAllowed(width, height).
void checkImageSize(const std::string& name, std::int64_t width, std::int64_t height);

/// @brief What a picture file's first bytes say it is.
enum class PictureFormat { Png, Jpeg, Other };

/// @brief PNG by its signature's first 4 bytes, JPEG by its start-of-image marker and the next
///        marker's 0xFF: what the texture decoder and pictureSize() both tell formats by.
PictureFormat pictureFormat(const unsigned char* bytes, std::size_t size);

/// @brief A PNG's or JPEG's size from its header, read from `file`'s start; `name` stands for it in
///        errors. Reads the PNG's first 24 bytes, or a JPEG's segment headers up to its frame header.
/// @throws InputError when it is neither, is cut before its size, or declares a size
///         checkImageSize() refuses.
PictureSize pictureSize(std::FILE* file, const std::string& name);

/// @brief pictureSize() of a file: what sizes a whole set of pictures before any is decoded
///        (train's memory check). @throws IoError when the file cannot be opened; as pictureSize().
PictureSize readTextureSize(const std::string& path);

} // namespace splatwarp
