#include "stage2/StageTwoDevice.h"

#include <atomic>

#include "core/Progress.h"

namespace splatwarp {
namespace {

std::atomic<StageTwoFunction>& cudaSlot()
{
    static std::atomic<StageTwoFunction> f{nullptr};
    return f;
}

} // namespace

void registerStageTwoCuda(StageTwoFunction cuda) { cudaSlot().store(cuda); }

StageTwoReport runStageTwo(Device device, GaussianCloud& cloud, const SampleSet& samples,
                           const std::vector<std::uint8_t>& moving, const std::vector<std::int32_t>& gaussianCell,
                           const StageTwoOptions& options,
                           const std::function<void(int, const GaussianCloud&)>& onEval, int evalEvery)
{
    const Device resolved = resolveDevice(device);
    const StageTwoFunction cuda = cudaSlot().load();
    if (resolved == Device::Cuda) {
        if (!cuda) {
            if (device == Device::Cuda) throw InputError("--device cuda: this build has no CUDA Stage II");
        } else {
            try {
                StageTwoReport r = cuda(cloud, samples, moving, gaussianCell, options, onEval, evalEvery);
                r.device = "cuda";
                return r;
            } catch (const DeviceMemoryError& e) {
                if (device == Device::Cuda)
                    throw DeviceMemoryError(msg(e.what(), " (--device cuda; --device auto would fall back to the CPU)"));
                progress(msg("Stage II: ", e.what(), "; running on the CPU instead"));
            }
        }
    }
    StageTwoReport r = optimiseStageTwo(cloud, samples, moving, gaussianCell, options, onEval, evalEvery);
    r.device = "cpu";
    return r;
}

} // namespace splatwarp
