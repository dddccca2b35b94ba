/// libFuzzer target: the `.spz` reader. The input is the inflated payload (header + Gaussians),
/// gzipped here so that mutations reach the decoder instead of failing the gzip CRC; the raw
/// input is also read as is, for the gzip and magic handling.
#include <zlib.h>

#include <cstddef>
#include <cstdint>
#include <string>

#include "core/Error.h"
#include "io/FormatReaders.h"

namespace {

std::string gzip(const std::uint8_t* data, std::size_t size)
{
    std::string out(size + size / 100 + 64, '\0');
    z_stream z{};
    deflateInit2(&z, 1, Z_DEFLATED, 16 + MAX_WBITS, 8, Z_DEFAULT_STRATEGY);
    z.next_in = const_cast<Bytef*>(data);
    z.avail_in = uInt(size);
    z.next_out = reinterpret_cast<Bytef*>(&out[0]);
    z.avail_out = uInt(out.size());
    deflate(&z, Z_FINISH);
    out.resize(z.total_out);
    deflateEnd(&z);
    return out;
}

void read(const std::string& bytes)
{
    splatwarp::ReadReport report;
    try {
        splatwarp::readSpz("fuzz-input", bytes, report);
    } catch (const splatwarp::Error&) {
    }
}

} // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
    read(gzip(data, size));
    read(std::string(reinterpret_cast<const char*>(data), size));
    return 0;
}
