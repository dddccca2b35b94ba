#pragma once
/// @file CudaBackends.h
/// @brief Start-up registration of the CUDA implementations with the core library (which
///        cannot link the kernels): tools/main.cpp calls registerBackends() under
///        SPLATWARP_WITH_CUDA.
#include <string>

namespace splatwarp::cuda {

/// @brief Why the current CUDA device cannot run this build's kernels (no driver, no device, or
///        a compute capability none of the compiled architectures runs on, see CudaArch.h);
///        empty when it can.
std::string cudaDeviceProblem();

/// @brief Whether a CUDA GPU is usable: cudaDeviceProblem() is empty.
bool cudaDeviceAvailable();

/// @brief Register the device probe, the CUDA Stage I update and warping, Stage II and the CUDA
///        rasteriser (see core/Device.h, deform/StageOneDevice.h, deform/WarpDevice.h,
///        stage2/StageTwoDevice.h, render/RenderDevice.h).
void registerBackends();

/// @brief Clear every slot registerBackends() fills: the CPU-only state (tests end with it).
void unregisterBackends();

} // namespace splatwarp::cuda
