#include "io/PlyBody.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>

#include "core/Error.h"

namespace splatwarp {

namespace {

template <typename T>
double loadAs(const char* p, bool swap)
{
    char bytes[sizeof(T)];
    std::memcpy(bytes, p, sizeof(T));
    if (swap) std::reverse(bytes, bytes + sizeof(T));
    T v;
    std::memcpy(&v, bytes, sizeof(T));
    return double(v);
}

// Decodes one binary scalar; the host is little-endian (as PlyWriter assumes), so big-endian
// files swap bytes.
double loadScalar(const char* p, PlyType t, bool swap)
{
    switch (t) {
    case PlyType::Int8: return loadAs<std::int8_t>(p, swap);
    case PlyType::UInt8: return loadAs<std::uint8_t>(p, swap);
    case PlyType::Int16: return loadAs<std::int16_t>(p, swap);
    case PlyType::UInt16: return loadAs<std::uint16_t>(p, swap);
    case PlyType::Int32: return loadAs<std::int32_t>(p, swap);
    case PlyType::UInt32: return loadAs<std::uint32_t>(p, swap);
    case PlyType::Float32: return loadAs<float>(p, swap);
    case PlyType::Float64: return loadAs<double>(p, swap);
    }
    return 0.0;
}

std::string recordName(const PlyElement& e, std::size_t row)
{
    return msg("element '", e.name, "' record ", row, " of ", e.count);
}

// Whitespace-separated tokens of an ASCII body, with line numbers for messages.
class AsciiTokens {
public:
    AsciiTokens(const std::string& path, const std::string& data, std::size_t pos, int line)
        : mPath(path), mData(data), mPos(pos), mLine(line) {}

    /// Next token as a number of record `row` of element `e` (named in messages).
    double number(const PlyElement& e, std::size_t row)
    {
        skipSpace();
        if (mPos >= mData.size())
            throw InputError(msg(mPath, ": truncated: unexpected end of file in ", recordName(e, row), " (header count too large?)"));
        const char* begin = mData.c_str() + mPos;
        char* end = nullptr;
        const double v = std::strtod(begin, &end);
        if (end == begin || (*end != '\0' && !std::isspace(static_cast<unsigned char>(*end)))) {
            std::size_t len = 0;
            while (begin[len] != '\0' && !std::isspace(static_cast<unsigned char>(begin[len])) && len < 32) ++len;
            throw InputError(msg(mPath, ": line ", mLine, ", ", recordName(e, row), ": expected a number, found '",
                                 std::string(begin, len), "'"));
        }
        mPos += std::size_t(end - begin);
        return v;
    }
    /// True when only whitespace is left.
    bool atEnd()
    {
        skipSpace();
        return mPos >= mData.size();
    }
    int line() const { return mLine; }

private:
    void skipSpace()
    {
        while (mPos < mData.size() && std::isspace(static_cast<unsigned char>(mData[mPos]))) {
            if (mData[mPos] == '\n') ++mLine;
            ++mPos;
        }
    }
    const std::string& mPath;
    const std::string& mData;
    std::size_t mPos;
    int mLine;
};

/// Parse the records of ASCII element `e` into `values` (row-major); elements with list
/// properties are only skipped.
void readAsciiElement(const std::string& path, const PlyElement& e, std::size_t bodyBytes, AsciiTokens& tokens,
                      std::vector<double>& values)
{
    const std::size_t np = e.properties.size();
    if (np == 0) return; // no values to read, whatever the count says
    // Every value takes at least 2 bytes ("0 "): refuse impossible counts before allocating.
    if (e.count > bodyBytes / (2 * np))
        throw InputError(msg(path, ": element '", e.name, "' declares ", e.count, " records of ", np,
                             " values, more than the ", bodyBytes, "-byte ASCII body can hold"));
    const bool keep = !e.hasLists();
    if (keep) values.reserve(e.count * np);
    for (std::size_t row = 0; row < e.count; ++row) {
        for (const PlyProperty& p : e.properties) {
            if (!p.isList) {
                const double x = tokens.number(e, row);
                if (keep) values.push_back(x);
                continue;
            }
            const double n = tokens.number(e, row);
            if (!(n >= 0) || n != std::floor(n) || n > double(bodyBytes))
                throw InputError(msg(path, ": line ", tokens.line(), ", ", recordName(e, row), ": bad list length ", n,
                                     " for property '", p.name, "'"));
            for (std::size_t k = 0; k < std::size_t(n); ++k) tokens.number(e, row);
        }
    }
}

/// Walk the variable-size records of binary element `e` (one with lists, e.g. faces) from `pos`;
/// returns the position after them.
std::size_t skipBinaryListElement(const std::string& path, const std::string& data, std::size_t pos,
                                  const PlyElement& e, bool swap)
{
    for (std::size_t row = 0; row < e.count; ++row) {
        for (const PlyProperty& p : e.properties) {
            const std::size_t cs = plyTypeSize(p.isList ? p.countType : p.type);
            if (data.size() - pos < cs)
                throw InputError(msg(path, ": truncated in ", recordName(e, row), " (property '", p.name, "')"));
            if (!p.isList) {
                pos += cs;
                continue;
            }
            const double n = loadScalar(data.data() + pos, p.countType, swap);
            pos += cs;
            const std::size_t itemBytes = plyTypeSize(p.type);
            if (!(n >= 0) || std::size_t(n) > (data.size() - pos) / itemBytes)
                throw InputError(msg(path, ": truncated or bad list length ", n, " in ", recordName(e, row),
                                     " (property '", p.name, "')"));
            pos += std::size_t(n) * itemBytes;
        }
    }
    return pos;
}

} // namespace

double PlyElementValues::get(std::size_t row, int prop) const
{
    const std::size_t np = mElement->properties.size();
    if (mBase) return loadScalar(mBase + row * mStride + mOffsets[prop], mElement->properties[prop].type, mSwap);
    return mAscii[row * np + std::size_t(prop)];
}

PlyBody::PlyBody(const std::string& path, const std::string& data, const PlyHeader& header, Trailing trailing) : mPath(path)
{
    mElements.resize(header.elements.size());
    for (std::size_t ei = 0; ei < header.elements.size(); ++ei) mElements[ei].mElement = &header.elements[ei];
    if (header.format == PlyFormat::Ascii)
        readAscii(data, header, trailing);
    else
        readBinary(data, header, trailing);
}

void PlyBody::readAscii(const std::string& data, const PlyHeader& header, Trailing trailing)
{
    // The header has one line per '\n' before bodyOffset.
    const int bodyLine = int(std::count(data.begin(), data.begin() + std::ptrdiff_t(header.bodyOffset), '\n')) + 1;
    AsciiTokens tokens(mPath, data, header.bodyOffset, bodyLine);
    const std::size_t bodyBytes = data.size() - header.bodyOffset;
    for (PlyElementValues& v : mElements) readAsciiElement(mPath, *v.mElement, bodyBytes, tokens, v.mAscii);
    if (trailing == Trailing::Refuse && !tokens.atEnd())
        throw InputError(msg(mPath, ": line ", tokens.line(),
                             ": data after the last element (header counts smaller than the body)"));
}

void PlyBody::readBinary(const std::string& data, const PlyHeader& header, Trailing trailing)
{
    const bool swap = header.format == PlyFormat::BinaryBigEndian;
    std::size_t pos = header.bodyOffset;
    for (PlyElementValues& v : mElements) {
        const PlyElement& e = *v.mElement;
        if (e.hasLists()) {
            pos = skipBinaryListElement(mPath, data, pos, e, swap);
            continue;
        }
        const std::size_t stride = e.recordBytes(), left = data.size() - pos;
        if (stride > 0 && e.count > left / stride)
            throw InputError(msg(mPath, ": truncated: element '", e.name, "' declares ", e.count, " records of ",
                                 stride, " bytes but only ", left, " bytes are left in the file (record ",
                                 left / stride, " is incomplete or missing)"));
        v.mBase = data.data() + pos;
        v.mStride = stride;
        std::size_t off = 0;
        for (const PlyProperty& p : e.properties) {
            v.mOffsets.push_back(off);
            off += plyTypeSize(p.type);
        }
        v.mSwap = swap;
        pos += stride * e.count;
    }
    if (trailing == Trailing::Refuse && pos != data.size())
        throw InputError(msg(mPath, ": ", data.size() - pos,
                             " bytes after the last element (header counts or types do not match the body)"));
}

const PlyElementValues& PlyBody::element(const std::string& name) const
{
    for (const PlyElementValues& v : mElements) {
        if (v.mElement->name != name) continue;
        if (v.mElement->hasLists())
            throw InputError(msg(mPath, ": element '", name, "' has list properties; cannot read it as Gaussians"));
        return v;
    }
    throw InputError(msg(mPath, ": no element '", name, "'"));
}

} // namespace splatwarp
