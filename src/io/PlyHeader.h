#pragma once
/// @file PlyHeader.h
/// @brief PLY header model and parser (any element/property layout, ASCII or binary).
#include <cstddef>
#include <string>
#include <vector>

namespace splatwarp {

/// @brief Body encoding named by the `format` line.
enum class PlyFormat { Ascii, BinaryLittleEndian, BinaryBigEndian };

/// @brief Scalar types of PLY properties (both the classic names and the int8..float64 aliases).
enum class PlyType { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };

/// @brief Size in bytes of a scalar of type t.
std::size_t plyTypeSize(PlyType t);

/// @brief One `property` line: a scalar, or a list (count type + value type).
struct PlyProperty {
    std::string name;
    PlyType type = PlyType::Float32;       ///< value type (of the items for a list)
    bool isList = false;
    PlyType countType = PlyType::UInt8;    ///< list length type (lists only)
};

/// @brief One `element` line and its properties.
struct PlyElement {
    std::string name;
    std::size_t count = 0;
    std::vector<PlyProperty> properties;
    int line = 0;                          ///< header line of the `element` declaration (1-based)

    /// @brief Index of the property with this name, or -1.
    int find(const std::string& propertyName) const;
    bool hasLists() const;
    /// @brief Bytes per binary record; only meaningful when !hasLists().
    std::size_t recordBytes() const;
};

/// @brief A parsed header; the body starts at bodyOffset in the file.
struct PlyHeader {
    PlyFormat format = PlyFormat::BinaryLittleEndian;
    std::vector<PlyElement> elements;
    std::size_t bodyOffset = 0;

    /// @brief The element with this name, or nullptr.
    const PlyElement* find(const std::string& elementName) const;
    /// @brief "ply-ascii", "ply-binary-le" or "ply-binary-be" (ReadReport::format).
    std::string formatName() const;
};

/// @brief One note per element other than `used` ("skipped element 'face' (12 records)"), the
///        first few only and then one line counting the rest: a header of 200,000 elements gave
///        200,000 progress lines.
std::vector<std::string> skippedElementNotes(const PlyHeader& header, const std::vector<std::string>& used);

/// @brief True when the data starts with the PLY magic line ("ply" + LF or CRLF).
bool hasPlyMagic(const std::string& data);

/// @brief Parse the header at the start of data (the whole file).
/// @throws InputError naming path and the header line for any malformed, unknown or missing part.
PlyHeader parsePlyHeader(const std::string& path, const std::string& data);

} // namespace splatwarp
