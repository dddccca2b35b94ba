/// libFuzzer target: the layout check that runs before OpenVDB reads a volume
/// (checkVdbLayout(), vdb/VdbLayout.h) on the raw input as a .vdb file: it must answer every cut,
/// forged length and offset with an InputError, read nothing past the input and never loop.
#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>

#include "vdb/VdbLayout.h"
#include "core/Error.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
    const std::string bytes(reinterpret_cast<const char*>(data), size);
    std::istringstream in(bytes, std::ios::binary);
    try {
        splatwarp::checkVdbLayout(in, size, "fuzz-input");
    } catch (const splatwarp::Error&) {
    }
    return 0;
}
