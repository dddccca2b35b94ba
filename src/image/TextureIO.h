#pragma once
/// @file TextureIO.h
/// @brief Reading texture images (PNG or JPEG, chosen by their first bytes) from files or from
///        bytes in memory (textures embedded in glTF/GLB files), as display values (image/Image.h).
#include <cstddef>
#include <string>

#include "image/Image.h"
#include "image/PictureSize.h"

namespace splatwarp {

/// @brief Read a PNG or JPEG file: RGB, or RGBA when a PNG has alpha; values / 255 as stored.
/// @throws IoError when the file cannot be opened, InputError when it is neither or is corrupt
///         (both name the file).
Image readTexture(const std::string& path);

/// @brief Decode PNG or JPEG bytes; `name` stands for the source in error messages.
/// @throws InputError naming `name` for anything else or a corrupt image.
Image decodeTexture(const unsigned char* bytes, std::size_t size, const std::string& name);

} // namespace splatwarp
