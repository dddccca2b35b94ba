#include "core/Error.h"

#include <cstdio>

namespace splatwarp {

namespace {
/// Length of the valid UTF-8 sequence starting at s[i] (>= 2 bytes), or 0.
std::size_t utf8Length(const std::string& s, std::size_t i)
{
    const unsigned char c = static_cast<unsigned char>(s[i]);
    const std::size_t n = c >= 0xf0 && c <= 0xf4 ? 4 : c >= 0xe0 ? 3 : c >= 0xc2 && c <= 0xdf ? 2 : 0;
    if (n == 0 || c >= 0xf5 || i + n > s.size()) return 0;
    for (std::size_t k = 1; k < n; ++k)
        if ((static_cast<unsigned char>(s[i + k]) & 0xc0) != 0x80) return 0;
    return n;
}
} // namespace

std::string printable(const std::string& text, std::size_t maxBytes)
{
    std::string out;
    for (std::size_t i = 0; i < text.size() && out.size() < maxBytes;) {
        const unsigned char c = static_cast<unsigned char>(text[i]);
        if ((c >= 0x20 && c < 0x7f) || c == '\n' || c == '\t') {
            out += char(c);
            ++i;
        } else if (const std::size_t n = c >= 0x80 ? utf8Length(text, i) : 0) {
            out.append(text, i, n);
            i += n;
        } else {
            char hex[5];
            std::snprintf(hex, sizeof(hex), "\\x%02x", c);
            out += hex;
            ++i;
        }
        if (out.size() >= maxBytes && i < text.size()) out += "...";
    }
    return out;
}

std::string printableLine(const std::string& text)
{
    std::string out;
    for (const char c : printable(text)) out += c == '\n' ? "\\n" : c == '\t' ? "\\t" : std::string(1, c);
    return out;
}

} // namespace splatwarp
