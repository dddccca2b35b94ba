#include "CudaBackends.h"

#include <cuda_runtime.h>

#include "FeaturesCuda.h"
#include "RasterizerCuda.h"
#include "StageOneCuda.h"
#include "StageTwoCuda.h"
#include "WarpCuda.h"
#include "core/Device.h"
#include "deform/StageOneDevice.h"
#include "deform/WarpDevice.h"
#include "render/RenderDevice.h"
#include "stage2/StageTwoDevice.h"

namespace splatwarp::cuda {

bool cudaDeviceAvailable()
{
    int count = 0;
    const cudaError_t e = cudaGetDeviceCount(&count);
    if (e != cudaSuccess) {
        cudaGetLastError(); // no driver / no device: not an error for the caller, just "no GPU"
        return false;
    }
    return count > 0;
}

void registerBackends()
{
    registerCudaProbe(&cudaDeviceAvailable);
    registerStageOneCuda(&makeStageOneCuda);
    registerWarpCuda(&warpPointsCuda, &warpSamplesCuda);
    registerStageTwoCuda(&optimiseStageTwoCuda);
    registerRenderCuda(&renderGaussiansCuda);
    registerSampleTargetsCuda(&evaluateSampleTargetsCuda);
    registerFeaturesCuda(&evaluateFeaturesCuda);
}

} // namespace splatwarp::cuda
