#pragma once
/// @file FuzzBytes.h
/// @brief Helpers of the fuzz targets that assemble files: little-endian u32, and a reader call
///        whose expected answer to bad bytes (splatwarp::Error) is swallowed.
#include <cstdint>
#include <string>

#include "core/Error.h"
#include "io/FormatReaders.h"

namespace fuzz {

inline void put32(std::string& s, std::uint32_t v)
{
    for (int b = 0; b < 4; ++b) s += char((v >> (8 * b)) & 0xff);
}

/// @brief reader(name, bytes, report) for readSpz, readGlb, ...; anything but splatwarp::Error escapes.
template <typename Reader>
void readQuietly(Reader reader, const std::string& bytes)
{
    splatwarp::ReadReport report;
    try {
        reader("fuzz-input", bytes, report);
    } catch (const splatwarp::Error&) {
    }
}

} // namespace fuzz
