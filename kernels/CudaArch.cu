// See CudaArch.h.
#include "kernels/CudaArch.h"

#include <cuda_runtime.h>

#include <cctype>
#include <sstream>

namespace splatwarp::cuda {
namespace {

__global__ void probeKernel() {}

/// One CMake architecture entry: "90", "75-real", "90-virtual", "90a-real".
struct ArchEntry {
    int value = -1; ///< 10 * major + minor; -1: not understood
    bool specific = false, sass = true, ptx = true;
};

ArchEntry parseArch(const std::string& text)
{
    ArchEntry e;
    std::size_t i = 0;
    int v = 0;
    while (i < text.size() && std::isdigit(static_cast<unsigned char>(text[i]))) v = 10 * v + (text[i++] - '0');
    if (i == 0) return e;
    if (i < text.size() && (text[i] == 'a' || text[i] == 'f')) {
        e.specific = true;
        ++i;
    }
    const std::string rest = text.substr(i);
    if (rest == "-real") e.ptx = false;
    else if (rest == "-virtual") e.sass = false;
    else if (!rest.empty()) return e;
    e.value = v;
    return e;
}

} // namespace

const char* compiledArchitectures()
{
#ifdef SPLATWARP_CUDA_ARCHITECTURES
    return SPLATWARP_CUDA_ARCHITECTURES;
#else
    return "";
#endif
}

bool architecturesRunOn(const std::string& archs, int major, int minor)
{
    std::string list = archs;
    for (char& c : list)
        if (c == ';') c = ',';
    std::stringstream in(list);
    std::string item;
    const int cc = 10 * major + minor;
    while (std::getline(in, item, ',')) {
        if (item.empty()) continue;
        const ArchEntry e = parseArch(item);
        if (e.value < 0) return true; // "all", "native", ...: leave it to the runtime
        if (e.sass && (e.specific ? e.value == cc : e.value / 10 == major && e.value % 10 <= minor)) return true;
        if (e.ptx && !e.specific && e.value <= cc) return true;
    }
    return false;
}

bool kernelImageLoads()
{
    cudaFuncAttributes a{};
    const cudaError_t e = cudaFuncGetAttributes(&a, probeKernel);
    if (e != cudaSuccess) cudaGetLastError(); // no kernel image for this device: not sticky
    return e == cudaSuccess;
}

} // namespace splatwarp::cuda
