#pragma once
/// @file CudaCheck.h
/// @brief Every CUDA runtime call and every kernel launch is checked: a failure throws
///        splatwarp::Error with file, line, the call and cudaGetErrorString (out of memory:
///        DeviceMemoryError, so callers can fall back to the CPU). Never exit().
#include <cuda_runtime.h>

#include "core/Device.h"
#include "core/Error.h"

namespace splatwarp::cuda {

/// @brief Throw for a failed CUDA call (what: the call's text).
[[noreturn]] inline void throwCudaError(cudaError_t e, const char* what, const char* file, int line)
{
    const std::string text = msg("CUDA error at ", file, ":", line, " in ", what, ": ", cudaGetErrorName(e), " (",
                                 cudaGetErrorString(e), ")");
    if (e == cudaErrorMemoryAllocation) {
        cudaGetLastError(); // out of memory is not sticky: clear it so the context stays usable
        throw DeviceMemoryError(text);
    }
    throw Error(text);
}

inline void checkCuda(cudaError_t e, const char* what, const char* file, int line)
{
    if (e != cudaSuccess) throwCudaError(e, what, file, line);
}

} // namespace splatwarp::cuda

/// Check a CUDA runtime call: SPLATWARP_CUDA_CHECK(cudaMemcpy(...)).
#define SPLATWARP_CUDA_CHECK(call) ::splatwarp::cuda::checkCuda((call), #call, __FILE__, __LINE__)
/// Check the launch just made (configuration errors; asynchronous faults surface at the next
/// synchronising call, which is checked too). No device synchronisation.
#define SPLATWARP_CUDA_CHECK_LAUNCH(kernelName) \
    ::splatwarp::cuda::checkCuda(cudaGetLastError(), "launch of " kernelName, __FILE__, __LINE__)
