#include "kernels/CudaBackends.h"

#include <cuda_runtime.h>

#include <atomic>
#include <string>

#include "kernels/CudaArch.h"
#include "kernels/FeaturesCuda.h"
#include "kernels/RasterizerCuda.h"
#include "kernels/StageOneCuda.h"
#include "kernels/StageTwoCuda.h"
#include "kernels/WarpCuda.h"
#include "core/Device.h"
#include "core/Error.h"
#include "core/Progress.h"
#include "deform/StageOneDevice.h"
#include "deform/WarpDevice.h"
#include "render/RenderDevice.h"
#include "stage2/StageTwoDevice.h"

namespace splatwarp::cuda {

std::string cudaDeviceProblem()
{
    int count = 0;
    if (cudaGetDeviceCount(&count) != cudaSuccess) {
        cudaGetLastError(); // no driver / no device: not an error for the caller, just "no GPU"
        return "no CUDA driver or device";
    }
    if (count == 0) return "no CUDA device";
    int device = 0;
    cudaDeviceProp prop{};
    if (cudaGetDevice(&device) != cudaSuccess || cudaGetDeviceProperties(&prop, device) != cudaSuccess) {
        cudaGetLastError();
        return "the CUDA device cannot be queried";
    }
    if (!architecturesRunOn(compiledArchitectures(), prop.major, prop.minor) || !kernelImageLoads())
        return msg("GPU ", device, " (", prop.name, ", compute capability ", prop.major, ".", prop.minor,
                   ") cannot run this build's kernels (compiled for ", compiledArchitectures(),
                   "; rebuild with -DCMAKE_CUDA_ARCHITECTURES=", prop.major, prop.minor, ")");
    return {};
}

bool cudaDeviceAvailable() { return cudaDeviceProblem().empty(); }

namespace {

/// The registered probe: a GPU this build cannot run on is said once (auto then runs on the CPU).
bool probeOnce()
{
    const std::string problem = cudaDeviceProblem();
    static std::atomic<bool> said{false};
    if (!problem.empty() && problem.rfind("GPU ", 0) == 0 && !said.exchange(true)) progress(problem);
    return problem.empty();
}

} // namespace

void registerBackends()
{
    registerCudaProbe(&probeOnce);
    registerStageOneCuda(&makeStageOneCuda);
    registerWarpCuda(&warpPointsCuda, &warpSamplesCuda);
    registerStageTwoCuda(&optimiseStageTwoCuda);
    registerRenderCuda(&renderGaussiansCuda);
    registerSampleTargetsCuda(&evaluateSampleTargetsCuda);
    registerFeaturesCuda(&evaluateFeaturesCuda);
}

void unregisterBackends()
{
    registerCudaProbe(nullptr);
    registerStageOneCuda(nullptr);
    registerWarpCuda(nullptr, nullptr);
    registerStageTwoCuda(nullptr);
    registerRenderCuda(nullptr);
    registerSampleTargetsCuda(nullptr);
    registerFeaturesCuda(nullptr);
}

} // namespace splatwarp::cuda
