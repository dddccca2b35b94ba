#pragma once
/// @file CudaBackends.h
/// @brief Start-up registration of the CUDA implementations with the core library (which
///        cannot link the kernels): tools/main.cpp calls registerBackends() under
///        SPLATWARP_WITH_CUDA.
namespace splatwarp::cuda {

/// @brief Whether a CUDA GPU is usable (cudaGetDeviceCount > 0 and no driver error).
bool cudaDeviceAvailable();

/// @brief Register the device probe, the CUDA Stage I update and warping, Stage II and the CUDA
///        rasteriser (see core/Device.h, deform/StageOneDevice.h, deform/WarpDevice.h,
///        stage2/StageTwoDevice.h, render/RenderDevice.h).
void registerBackends();

} // namespace splatwarp::cuda
