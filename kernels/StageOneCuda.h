#pragma once
/// @file StageOneCuda.h
/// @brief The Stage I per-Gaussian update on the GPU (double precision, like the CPU): the rest
///        model and rig are uploaded once; each update uploads the node transforms and downloads
///        the deformed model. No CUDA types here.
#include <memory>

#include "deform/StageOneDevice.h"

namespace splatwarp::cuda {

/// @brief A StageOneEngine on the current CUDA device (registered by registerBackends()).
/// @throws DeviceMemoryError when the rest model or rig does not fit (the message names the buffer)
std::unique_ptr<StageOneEngine> makeStageOneCuda(const GaussianCloud& rest, const StageOneRig& rig,
                                                 std::size_t nodeCount, const StageOneOptions& options);

} // namespace splatwarp::cuda
