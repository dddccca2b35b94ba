#include "render/RenderDevice.h"

#include <atomic>

#include "core/Progress.h"

namespace splatwarp {
namespace {

std::atomic<RenderFunction>& cudaSlot()
{
    static std::atomic<RenderFunction> f{nullptr};
    return f;
}

} // namespace

void registerRenderCuda(RenderFunction cuda) { cudaSlot().store(cuda); }

Image renderGaussians(Device device, const GaussianCloud& cloud, const Camera& camera, const RenderOptions& options,
                      Device* used)
{
    const RenderFunction cuda = cudaSlot().load();
    return runOnDevice(
        device, "rasteriser", cuda != nullptr, [&] { return cuda(cloud, camera, options); },
        [&] { return renderGaussians(cloud, camera, options); }, used);
}

} // namespace splatwarp
