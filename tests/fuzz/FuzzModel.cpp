/// libFuzzer target: readGaussiansFromBytes() (format detection, PLY header and body, compressed
/// PLY, .splat, .spz, the NaN/Inf policy). Built twice, as fuzz_ply and fuzz_compressed_ply, with
/// different seed corpora. InputError/IoError are the expected answer to bad bytes; anything else
/// (another exception, a sanitizer report, a crash) is a finding.
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/Error.h"
#include "io/GaussianIO.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
    const std::string bytes(reinterpret_cast<const char*>(data), size);
    splatwarp::ReadOptions options;
    options.dropInvalid = size % 2 == 1; // both NaN/Inf policies
    try {
        splatwarp::readGaussiansFromBytes("fuzz-input", bytes, options);
    } catch (const splatwarp::Error&) {
    }
    return 0;
}
