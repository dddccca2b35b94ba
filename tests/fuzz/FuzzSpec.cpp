/// libFuzzer target: parseDeformSpec() (the deformation spec JSON).
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/Error.h"
#include "deform/DeformSpec.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
    try {
        splatwarp::parseDeformSpec(std::string(reinterpret_cast<const char*>(data), size), "fuzz-input");
    } catch (const splatwarp::Error&) {
    }
    return 0;
}
