/// libFuzzer target: the `.splat` reader without format detection (plausibility test and decode).
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/Error.h"
#include "io/FormatReaders.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
    const std::string bytes(reinterpret_cast<const char*>(data), size);
    splatwarp::ReadReport report;
    try {
        splatwarp::readSplat("fuzz-input", bytes, report);
    } catch (const splatwarp::Error&) {
    }
    return 0;
}
