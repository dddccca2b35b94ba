/// libFuzzer target: the `.spz` version 4 reader. The input is read as is (header, TOC and zstd
/// handling), and again as the raw attribute bytes of a file this target assembles: the first three
/// bytes pick the SH degree, flags and fractional bits, the rest is split into the attribute
/// streams (zstd-compressed here with a correct table of contents) so that mutations reach the
/// decoder past zstd's framing.
#include <zstd.h>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "FuzzBytes.h"

namespace {

using fuzz::put32;

void read(const std::string& bytes) { fuzz::readQuietly(splatwarp::readSpz, bytes); }

std::string assemble(const std::uint8_t* data, std::size_t size)
{
    const int degree = data[0] % 5, rest = (degree + 1) * (degree + 1) - 1;
    const std::size_t per = 9 + 1 + 3 + 3 + 4 + 3 * std::size_t(rest), n = (size - 3) / per;
    const std::size_t sizes[6] = {9 * n, n, 3 * n, 3 * n, 4 * n, 3 * std::size_t(rest) * n};
    const int streams = rest ? 6 : 5;
    const std::string ext = data[1] & 2 ? std::string("\x01\x00\x01\x00\x04\x00\x00\x00" "abcd", 12) : std::string();
    std::string out = "NGSP";
    put32(out, 4);
    put32(out, std::uint32_t(n));
    out += char(degree);
    out += char(data[2]);
    out += char(data[1]);
    out += char(streams);
    put32(out, std::uint32_t(32 + ext.size()));
    out.append(12, '\0');
    out += ext;
    std::string body;
    const char* src = reinterpret_cast<const char*>(data) + 3;
    for (int s = 0; s < streams; ++s) {
        std::string z(ZSTD_compressBound(sizes[s]), '\0');
        z.resize(ZSTD_compress(&z[0], z.size(), src, sizes[s], 1));
        src += sizes[s];
        put32(out, std::uint32_t(z.size()));
        put32(out, 0);
        put32(out, std::uint32_t(sizes[s]));
        put32(out, 0);
        body += z;
    }
    return out + body;
}

} // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
    read(std::string(reinterpret_cast<const char*>(data), size));
    if (size > 3) read(assemble(data, size));
    return 0;
}
