#pragma once
/// @file ImageIO.h
/// @brief PNG (8-bit sRGB, libpng) and OpenEXR (linear half/float RGBA) image files, written
///        atomically.
/// @note  Renders hold display values (image/Image.h): a PNG stores them as they are (what
///        graphdeco's renderer and the splat viewers show), writeImage() stores an EXR as their
///        linear decode (displayToLinear()).
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "image/Image.h"
#include "image/PictureSize.h"

namespace splatwarp {

/// @brief How PNG values map to Image values.
enum class PngValues {
    Display, ///< the stored 8-bit values / 255 as they are (renders, photographs, metrics)
    Linear   ///< the image holds linear light: encode linear -> sRGB on write, decode on read
};

/// @brief Options for writePng().
struct PngWriteOptions {
    PngValues values = PngValues::Display;
    /// Keep the alpha channel of a 4-channel image (straight alpha). Default off: renders are already
    /// composited over their background, and RGB is what every viewer shows as rendered.
    bool alpha = false;
};

/// @brief The 8-bit values writePng() stores, [height, width, 3 or 4 with options.alpha] (the
///        Python module's render() returns them).
/// @throws InputError for an image without 3 or 4 channels; `name` stands for it in the message.
std::vector<std::uint8_t> pngBytes(const std::string& name, const Image& image, const PngWriteOptions& options = {});
/// @brief Write an 8-bit PNG (RGB, or RGBA with options.alpha) atomically.
/// @throws InputError for an image without 3 or 4 channels; IoError when the file cannot be written.
void writePng(const std::string& path, const Image& image, const PngWriteOptions& options = {});
/// @brief Read any PNG as RGB (or RGBA when the file has alpha), values in [0, 1].
/// @throws IoError/InputError naming the file.
Image readPng(const std::string& path, PngValues values = PngValues::Display);
/// @brief Decode PNG bytes as readPng() does; `name` stands for them in error messages.
/// @throws InputError for a corrupt PNG, one with a side over kMaxImageSide (core/Camera.h) or more
///         pixels than its bytes can hold, checked before the pixels are allocated.
Image decodePng(const unsigned char* bytes, std::size_t size, const std::string& name, PngValues values = PngValues::Display);

/// @brief Pixel type of EXR channels.
enum class ExrPixelType { Half, Float };

/// @brief Write an OpenEXR (RGB, or RGBA for 4 channels; ZIP compression) atomically, values as
///        they are (callers pass linear light; writeImage() decodes a render first).
/// @note  EXR consumers treat RGB as premultiplied by alpha: that holds for renders over the
///        default black background (up to the sRGB curve applied after compositing).
void writeExr(const std::string& path, const Image& image, ExrPixelType type = ExrPixelType::Half);
/// @brief Read the R, G, B (and A when present) channels of an OpenEXR file as float.
Image readExr(const std::string& path);

/// @brief Write a render (display values) as .png (the values as they are) or .exr (half, their
///        linear decode, displayToLinear()), chosen by the extension (case-insensitive).
/// @throws InputError for any other extension.
void writeImage(const std::string& path, const Image& image);
/// @brief True when the path ends in .png or .exr (case-insensitive).
bool isImagePath(const std::string& path);
/// @brief The file name's extension with its dot, lower-cased ("" when it has none).
std::string lowerExtension(const std::string& path);
/// @brief Read what writeImage() wrote (or any PNG/EXR) as display values: PNG as stored, EXR
///        encoded from linear (linearToDisplay()).
/// @throws InputError for any other extension; IoError/InputError naming an unreadable file.
Image readImage(const std::string& path);

} // namespace splatwarp
