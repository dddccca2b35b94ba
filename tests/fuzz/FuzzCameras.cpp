/// libFuzzer target: parseCameraFile() (graphdeco cameras.json and NeRF transforms.json).
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/Error.h"
#include "io/CameraFiles.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
    splatwarp::CameraFileOptions options;
    options.width = size % 2 == 1 ? 64 : 0; // with and without a fallback image size
    options.height = options.width;
    try {
        splatwarp::parseCameraFile(std::string(reinterpret_cast<const char*>(data), size), "fuzz-input", options);
    } catch (const splatwarp::Error&) {
    }
    return 0;
}
