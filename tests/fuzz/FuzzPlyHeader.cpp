/// libFuzzer target: parsePlyHeader() alone (the header grammar, counts, property lists).
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/Error.h"
#include "io/PlyHeader.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
    const std::string bytes(reinterpret_cast<const char*>(data), size);
    try {
        splatwarp::parsePlyHeader("fuzz-input", bytes);
    } catch (const splatwarp::Error&) {
    }
    return 0;
}
