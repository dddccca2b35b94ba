#pragma once
/// @file CudaArch.h
/// @brief Whether this build's kernels can run on a GPU: its compute capability against the
///        architectures compiled in (CMAKE_CUDA_ARCHITECTURES). A GPU they cannot run on would
///        fail at the first launch, after --device auto had chosen it; the probe refuses it
///        instead, so auto runs on the CPU.
#include <string>

namespace splatwarp::cuda {

/// @brief CMAKE_CUDA_ARCHITECTURES of this build, entries separated by ',' (e.g. "75-real,90").
const char* compiledArchitectures();

/// @brief Whether code built for `archs` (CMake's syntax, ',' or ';' separated) runs on compute
///        capability major.minor: SASS ("XY" or "XY-real") on the same major and a minor >= Y,
///        architecture-specific SASS ("90a") on X.Y only, PTX ("XY" or "XY-virtual") on any
///        capability >= X.Y (the driver JIT-compiles it). Entries it cannot read ("all",
///        "native") count as running: the runtime check (kernelImageLoads()) decides.
bool architecturesRunOn(const std::string& archs, int major, int minor);

/// @brief Whether the current device can load this build's kernels (cudaFuncGetAttributes of
///        a trivial kernel): the runtime's own answer to architecturesRunOn().
bool kernelImageLoads();

} // namespace splatwarp::cuda
