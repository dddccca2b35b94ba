#include "io/PlyHeader.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdlib>
#include <sstream>
#include <unordered_set>

#include "core/Error.h"

namespace splatwarp {

namespace {

bool parseType(const std::string& s, PlyType& t)
{
    struct Name {
        const char* name;
        PlyType type;
    };
    static const Name names[] = {
        {"char", PlyType::Int8},     {"int8", PlyType::Int8},       {"uchar", PlyType::UInt8},
        {"uint8", PlyType::UInt8},   {"short", PlyType::Int16},     {"int16", PlyType::Int16},
        {"ushort", PlyType::UInt16}, {"uint16", PlyType::UInt16},   {"int", PlyType::Int32},
        {"int32", PlyType::Int32},   {"uint", PlyType::UInt32},     {"uint32", PlyType::UInt32},
        {"float", PlyType::Float32}, {"float32", PlyType::Float32}, {"double", PlyType::Float64},
        {"float64", PlyType::Float64}};
    for (const Name& n : names)
        if (s == n.name) {
            t = n.type;
            return true;
        }
    return false;
}

bool parseCount(const std::string& s, std::size_t& count)
{
    if (s.empty() || s.size() > 19) return false; // > 19 digits cannot be a sane count
    for (char c : s)
        if (!std::isdigit(static_cast<unsigned char>(c))) return false;
    count = std::size_t(std::strtoull(s.c_str(), nullptr, 10));
    return true;
}

} // namespace

std::size_t plyTypeSize(PlyType t)
{
    switch (t) {
    case PlyType::Int8:
    case PlyType::UInt8: return 1;
    case PlyType::Int16:
    case PlyType::UInt16: return 2;
    case PlyType::Int32:
    case PlyType::UInt32:
    case PlyType::Float32: return 4;
    case PlyType::Float64: return 8;
    }
    return 0;
}

int PlyElement::find(const std::string& propertyName) const
{
    for (std::size_t i = 0; i < properties.size(); ++i)
        if (properties[i].name == propertyName) return int(i);
    return -1;
}

bool PlyElement::hasLists() const
{
    for (const PlyProperty& p : properties)
        if (p.isList) return true;
    return false;
}

std::size_t PlyElement::recordBytes() const
{
    std::size_t bytes = 0;
    for (const PlyProperty& p : properties) bytes += plyTypeSize(p.type);
    return bytes;
}

const PlyElement* PlyHeader::find(const std::string& elementName) const
{
    for (const PlyElement& e : elements)
        if (e.name == elementName) return &e;
    return nullptr;
}

std::string PlyHeader::formatName() const
{
    switch (format) {
    case PlyFormat::Ascii: return "ply-ascii";
    case PlyFormat::BinaryLittleEndian: return "ply-binary-le";
    case PlyFormat::BinaryBigEndian: return "ply-binary-be";
    }
    return "ply";
}

std::vector<std::string> skippedElementNotes(const PlyHeader& header, const std::vector<std::string>& used)
{
    constexpr std::size_t kShown = 5;
    std::vector<std::string> notes;
    std::size_t skipped = 0, records = 0;
    for (const PlyElement& e : header.elements) {
        if (std::find(used.begin(), used.end(), e.name) != used.end()) continue;
        if (++skipped <= kShown) notes.push_back(msg("skipped element '", e.name, "' (", e.count, " records)"));
        else records += e.count;
    }
    if (skipped > kShown) notes.push_back(msg("skipped ", skipped - kShown, " more elements (", records, " records)"));
    return notes;
}

bool hasPlyMagic(const std::string& data)
{
    return data.compare(0, 4, "ply\n") == 0 || data.compare(0, 5, "ply\r\n") == 0;
}

PlyHeader parsePlyHeader(const std::string& path, const std::string& data)
{
    if (!hasPlyMagic(data)) throw InputError(msg(path, ": not a PLY file (first line is not 'ply')"));
    PlyHeader h;
    bool haveFormat = false;
    // Names seen so far, so duplicate checks stay linear in the header size (200k lines).
    std::unordered_set<std::string> elementNames, propertyNames;
    std::size_t pos = 0;
    for (int lineNo = 1;; ++lineNo) {
        const std::size_t eol = data.find('\n', pos);
        if (eol == std::string::npos)
            throw InputError(msg(path, ": PLY header has no 'end_header' line (", lineNo - 1, " lines read)"));
        std::string line = data.substr(pos, eol - pos);
        pos = eol + 1;
        if (!line.empty() && line.back() == '\r') line.pop_back(); // tolerate CRLF headers
        if (lineNo == 1) continue;                                 // the magic

        std::istringstream in(line);
        std::string key;
        in >> key;
        const auto where = [&] { return msg(path, ": PLY header line ", lineNo, " '", line, "': "); };
        if (key.empty() || key == "comment" || key == "obj_info") continue;
        if (key == "end_header") {
            if (!haveFormat) throw InputError(where() + "no 'format' line before end_header");
            h.bodyOffset = pos;
            return h;
        }
        std::vector<std::string> words;
        for (std::string w; in >> w;) words.push_back(w);
        if (key == "format") {
            if (words.size() != 2 || words[1] != "1.0") throw InputError(where() + "expected 'format <encoding> 1.0'");
            if (words[0] == "ascii") h.format = PlyFormat::Ascii;
            else if (words[0] == "binary_little_endian") h.format = PlyFormat::BinaryLittleEndian;
            else if (words[0] == "binary_big_endian") h.format = PlyFormat::BinaryBigEndian;
            else throw InputError(where() + "unknown format '" + words[0] + "'");
            haveFormat = true;
        } else if (key == "element") {
            PlyElement e;
            if (words.size() != 2 || !parseCount(words[1], e.count))
                throw InputError(where() + "expected 'element <name> <count>' with a non-negative integer count");
            e.name = words[0];
            e.line = lineNo;
            if (!elementNames.insert(e.name).second) throw InputError(where() + "element '" + e.name + "' declared twice");
            h.elements.push_back(e);
            propertyNames.clear();
        } else if (key == "property") {
            if (h.elements.empty()) throw InputError(where() + "property before any element");
            PlyProperty p;
            bool ok = false;
            if (words.size() == 4 && words[0] == "list") {
                p.isList = true;
                ok = parseType(words[1], p.countType) && parseType(words[2], p.type);
            } else if (words.size() == 2)
                ok = parseType(words[0], p.type);
            if (!ok) throw InputError(where() + "expected 'property <type> <name>' or 'property list <type> <type> <name>' with a known type");
            p.name = words.back();
            PlyElement& e = h.elements.back();
            if (!propertyNames.insert(p.name).second)
                throw InputError(where() + "property '" + p.name + "' declared twice in element '" + e.name + "'");
            e.properties.push_back(p);
        } else {
            throw InputError(where() + "unknown header keyword '" + key + "'");
        }
    }
}

} // namespace splatwarp
