#pragma once
/// @file PlyBody.h
/// @brief Locates every element of a PLY body (checking sizes against the file before anything
///        is allocated) and gives (record, property) access to the scalar elements.
#include <cstddef>
#include <string>
#include <vector>

#include "io/PlyHeader.h"

namespace splatwarp {

/// @brief Values of one element without list properties, read as double (exact for every PLY
///        scalar type, including uint32 bit fields).
class PlyElementValues {
public:
    /// @brief Value of property `prop` (index into PlyElement::properties) of record `row`.
    double get(std::size_t row, int prop) const;
    const PlyElement& element() const { return *mElement; }
    std::size_t count() const { return mElement->count; }

private:
    friend class PlyBody;
    const PlyElement* mElement = nullptr;
    // Binary: records at mBase + row * mStride, property offsets and types.
    const char* mBase = nullptr;
    std::size_t mStride = 0;
    std::vector<std::size_t> mOffsets;
    bool mSwap = false;
    // ASCII: values parsed up front, row-major.
    std::vector<double> mAscii;
};

/// @brief The body of a PLY file: every element located; scalar elements readable.
class PlyBody {
public:
    /// @brief What follows the last element: refused (a model: header counts that do not match), or
    ///        allowed (a mesh for Assimp, which reads files that carry a few bytes more).
    enum class Trailing { Refuse, Allow };

    /// @brief Walk the body of `data` (the whole file) laid out by `header`.
    /// @throws InputError naming path, element and record when the body is truncated, has bytes
    ///         left over (Trailing::Refuse), or (ASCII) holds a token that is not a number.
    PlyBody(const std::string& path, const std::string& data, const PlyHeader& header, Trailing trailing = Trailing::Refuse);

    /// @brief The values of the named element.
    /// @throws InputError if there is no such element or it has list properties.
    const PlyElementValues& element(const std::string& name) const;

private:
    void readAscii(const std::string& data, const PlyHeader& header, Trailing trailing);
    void readBinary(const std::string& data, const PlyHeader& header, Trailing trailing);

    std::string mPath;
    std::vector<PlyElementValues> mElements;
};

} // namespace splatwarp
