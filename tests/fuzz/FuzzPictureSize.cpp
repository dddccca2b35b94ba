/// libFuzzer target: pictureSize() (a PNG's IHDR, a JPEG's segments up to its frame header), the
/// size train reads of every picture before decoding any.
#include <cstddef>
#include <cstdint>
#include <cstdio>

#include "core/Error.h"
#include "image/PictureSize.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
    if (size == 0) return 0; // fmemopen refuses an empty buffer
    std::FILE* f = fmemopen(const_cast<std::uint8_t*>(data), size, "rb");
    if (!f) return 0;
    try {
        splatwarp::pictureSize(f, "fuzz-input");
    } catch (const splatwarp::Error&) {
    }
    std::fclose(f);
    return 0;
}
