#include "CudaBackends.h"

#include <cuda_runtime.h>

#include "FeaturesCuda.h"
#include "RasterizerCuda.h"
#include "StageTwoCuda.h"
#include "core/Device.h"
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
    registerStageTwoCuda(&optimiseStageTwoCuda);
    registerRenderCuda(&renderGaussiansCuda);
    registerSampleTargetsCuda(&evaluateSampleTargetsCuda);
    registerFeaturesCuda(&evaluateFeaturesCuda);
}

} // namespace splatwarp::cuda
