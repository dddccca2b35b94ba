#pragma once
/// @file Image.h
/// @brief A float image (interleaved channels, row-major, top row first) and the sRGB transfer
///        functions.
/// @note  Colour convention: renders hold display (sRGB-encoded) values, because splat colours
///        0.5 + C0 f_dc (+ SH) are display values: 3DGS models are trained on sRGB photographs and
///        graphdeco's renderer, PlayCanvas and the usual viewers show that value as it is (glTF
///        KHR_gaussian_splatting's default colour space is srgb_rec709_display). PNG files store
///        the value as it is; EXR files store its linear decode (image/ImageIO.h).
#include <cstddef>
#include <vector>

namespace splatwarp {

/// @brief width x height pixels of `channels` floats (3 = RGB, 4 = RGBA), display values unless stated.
struct Image {
    int width = 0, height = 0, channels = 0;
    std::vector<float> pixels; ///< [height, width, channels]

    Image() = default;
    /// @brief A width x height image with every channel set to `fill`.
    Image(int w, int h, int c, float fill = 0.0f)
        : width(w), height(h), channels(c), pixels(std::size_t(w) * std::size_t(h) * std::size_t(c), fill)
    {
    }
    bool empty() const { return pixels.empty(); }
    std::size_t index(int x, int y, int c = 0) const
    {
        return (std::size_t(y) * std::size_t(width) + std::size_t(x)) * std::size_t(channels) + std::size_t(c);
    }
    float& at(int x, int y, int c) { return pixels[index(x, y, c)]; }
    float at(int x, int y, int c) const { return pixels[index(x, y, c)]; }
};

/// @brief sRGB encoding of a linear value (IEC 61966-2-1 piecewise curve); input clamped to [0, 1].
float linearToSrgb(float linear);
/// @brief Inverse of linearToSrgb() on [0, 1].
float srgbToLinear(float encoded);

/// @brief The image with its colour channels decoded display -> linear light (alpha unchanged).
///        The sRGB curve is extended past 1 (same formula) and below 0 (the linear segment), so
///        out-of-range splat colours survive the round trip through an EXR.
Image displayToLinear(const Image& image);
/// @brief Inverse of displayToLinear().
Image linearToDisplay(const Image& image);

} // namespace splatwarp
