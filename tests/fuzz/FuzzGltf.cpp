/// libFuzzer target: the `.glb` (KHR_gaussian_splatting) reader. The input is read as is, and
/// again as the JSON chunk of a file whose BIN chunk is 64 KiB of float 0.25 (a valid value for
/// every attribute), so that mutations of the JSON reach the accessor and attribute logic.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>

#include "FuzzBytes.h"

namespace {

using fuzz::put32;

void read(const std::string& bytes) { fuzz::readQuietly(splatwarp::readGlb, bytes); }

std::string withBin(const std::uint8_t* data, std::size_t size)
{
    static const std::string bin = [] {
        std::string b(65536, '\0');
        const float q = 0.25f;
        for (std::size_t i = 0; i < b.size(); i += 4) std::memcpy(&b[i], &q, 4);
        return b;
    }();
    std::string json(reinterpret_cast<const char*>(data), size);
    json.append((4 - json.size() % 4) % 4, ' ');
    std::string out = "glTF";
    put32(out, 2);
    put32(out, std::uint32_t(12 + 8 + json.size() + 8 + bin.size()));
    put32(out, std::uint32_t(json.size()));
    put32(out, 0x4E4F534A);
    out += json;
    put32(out, std::uint32_t(bin.size()));
    put32(out, 0x004E4942);
    return out + bin;
}

} // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
    read(std::string(reinterpret_cast<const char*>(data), size));
    read(withBin(data, size));
    return 0;
}
