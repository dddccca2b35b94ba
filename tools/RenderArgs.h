#pragma once
/// @file RenderArgs.h
/// @brief Parsing of the flag values shared by `render` and `bench render` (--size, --background).
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "core/Camera.h"
#include "core/Error.h"
#include "core/SmallMath.h"

namespace splatwarp::cli {

/// @brief "WxH" -> width, height (each in [1, kMaxImageSide]). @throws UsageError otherwise.
inline void parseImageSize(const std::string& text, int& width, int& height)
{
    // strtol, not sscanf("%d"): an out-of-range %d is undefined, strtol saturates and says so.
    const auto side = [&](const char* from, char** end) {
        errno = 0;
        const long v = std::strtol(from, end, 10);
        const bool ok = *end != from && errno == 0 && v >= 1 && v <= kMaxImageSide && std::isdigit((unsigned char)*from);
        if (!ok)
            throw UsageError(msg("--size must be WIDTHxHEIGHT, each a whole number from 1 to ", kMaxImageSide,
                                 ", got '", text, "'"));
        return int(v);
    };
    char* end = nullptr;
    width = side(text.c_str(), &end);
    if (*end != 'x' && *end != 'X')
        throw UsageError(msg("--size must be WIDTHxHEIGHT, e.g. 800x600, got '", text, "'"));
    height = side(end + 1, &end);
    if (*end != '\0') throw UsageError(msg("--size must be WIDTHxHEIGHT, e.g. 800x600, got '", text, "'"));
}

/// @brief "r,g,b" (display values, each in [0, 1]) -> colour. @throws UsageError otherwise.
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
