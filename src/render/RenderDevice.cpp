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
    const Device resolved = resolveDevice(device);
    const RenderFunction cuda = cudaSlot().load();
    if (resolved == Device::Cuda) {
        if (!cuda) {
            if (device == Device::Cuda) throw InputError("--device cuda: this build has no CUDA rasteriser");
        } else {
            try {
                Image image = cuda(cloud, camera, options);
                if (used) *used = Device::Cuda;
                return image;
            } catch (const DeviceMemoryError& e) {
                if (device == Device::Cuda)
                    throw DeviceMemoryError(msg(e.what(), " (--device cuda; --device auto would fall back to the CPU)"));
                progress(msg("render: ", e.what(), "; rendering on the CPU instead"));
            }
        }
    }
    if (used) *used = Device::Cpu;
    return renderGaussians(cloud, camera, options);
}

} // namespace splatwarp
