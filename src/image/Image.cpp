#include "image/Image.h"

#include <algorithm>
#include <cmath>

namespace splatwarp {

float linearToSrgb(float linear)
{
    const float v = std::clamp(linear, 0.0f, 1.0f);
    return v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
}

float srgbToLinear(float encoded)
{
    const float v = std::clamp(encoded, 0.0f, 1.0f);
    return v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f);
}

namespace {

float decodeExtended(float v) { return v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f); }
float encodeExtended(float v) { return v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f; }

template <class F>
Image mapColour(const Image& image, F f)
{
    Image out = image;
    const std::size_t colour = std::size_t(image.channels < 3 ? image.channels : 3);
    for (std::size_t i = 0; i < out.pixels.size(); ++i)
        if (i % std::size_t(image.channels) < colour) out.pixels[i] = f(out.pixels[i]);
    return out;
}

} // namespace

Image displayToLinear(const Image& image) { return mapColour(image, decodeExtended); }
Image linearToDisplay(const Image& image) { return mapColour(image, encodeExtended); }

} // namespace splatwarp
