#include "render/RenderDevice.h"

#include "core/Progress.h"

namespace splatwarp {
namespace {

CudaSlot<RenderFunction> cudaSlot;

} // namespace

void registerRenderCuda(RenderFunction cuda) { cudaSlot.set(cuda); }

Image renderGaussiansOn(const GaussianCloud& cloud, const Camera& camera, const RenderOptions& options, Device* used)
{
    const RenderFunction cuda = cudaSlot.get();
    return runOnDevice(
        options.device, "rasteriser", cuda != nullptr, [&] { return cuda(cloud, camera, options); },
        [&] { return renderGaussians(cloud, camera, options); }, used);
}

} // namespace splatwarp
