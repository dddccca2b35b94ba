#pragma once
/// @file BitmapFont.h
/// @brief A tiny built-in 5x7 bitmap font for labels on images (no font files needed).
/// @note  Covers A-Z (lower case is drawn as upper case), 0-9, space and . , : ; - _ + = / \ ( ) [ ] % # ' ! ? < > *.
///        Any other character is drawn as '?'.
#include <string>

#include "core/SmallMath.h"
#include "image/Image.h"

namespace splatwarp {

constexpr int kGlyphWidth = 5;   ///< glyph cell width in font pixels
constexpr int kGlyphHeight = 7;  ///< glyph cell height in font pixels
constexpr int kGlyphAdvance = 6; ///< horizontal advance: one pixel of spacing

/// @brief True when the glyph of `c` has font pixel (col, row) set; col in [0,5), row in [0,7).
bool glyphPixel(char c, int col, int row);

/// @brief Width in image pixels of a text line drawn at a scale (each font pixel = scale x scale).
int textWidth(const std::string& text, int scale);

/// @brief Draw a text line with its top-left corner at (x, y); pixels outside the image are clipped.
///        Sets the first three channels to `colour` (and alpha to 1 for 4-channel images).
void drawText(Image& image, int x, int y, const std::string& text, int scale, const Vec3f& colour);

} // namespace splatwarp
