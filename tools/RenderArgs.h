#pragma once
/// @file RenderArgs.h
/// @brief Parsing of the flag values shared by `render` and `bench render` (--size, --background).
#include <cstdio>
#include <string>

#include "core/Error.h"
#include "core/SmallMath.h"

namespace splatwarp::cli {

/// @brief "WxH" -> width, height (both positive). @throws UsageError otherwise.
inline void parseImageSize(const std::string& text, int& width, int& height)
{
    char x = 0, rest = 0;
    if (std::sscanf(text.c_str(), "%d%c%d%c", &width, &x, &height, &rest) != 3 || (x != 'x' && x != 'X') ||
        width <= 0 || height <= 0)
        throw UsageError(msg("--size must be WIDTHxHEIGHT with positive integers, got '", text, "'"));
}

/// @brief "r,g,b" (linear, each in [0, 1]) -> colour. @throws UsageError otherwise.
inline Vec3f parseColour(const std::string& text)
{
    Vec3f c;
    char rest = 0;
    if (std::sscanf(text.c_str(), "%f,%f,%f%c", &c.x, &c.y, &c.z, &rest) != 3)
        throw UsageError(msg("--background must be r,g,b (three numbers in [0, 1]), got '", text, "'"));
    for (int i = 0; i < 3; ++i)
        if (!(c[i] >= 0.0f && c[i] <= 1.0f))
            throw UsageError(msg("--background components must lie in [0, 1], got '", text, "'"));
    return c;
}

} // namespace splatwarp::cli
