#include "stage2/StageTwoDevice.h"

#include "core/Progress.h"

namespace splatwarp {
namespace {

CudaSlot<StageTwoFunction> cudaSlot;

} // namespace

void registerStageTwoCuda(StageTwoFunction cuda) { cudaSlot.set(cuda); }

StageTwoReport runStageTwo(GaussianCloud& cloud, const SampleSet& samples,
                           const std::vector<std::uint8_t>& moving, const std::vector<std::int32_t>& gaussianCell,
                           const StageTwoOptions& options,
                           const std::function<void(int, const GaussianCloud&)>& onEval, int evalEvery,
                           const std::function<void()>& onRestart)
{
    const StageTwoFunction cuda = cudaSlot.get();
    Device used = Device::Cpu;
    bool seen = false; // whether onEval saw an iteration of the GPU run
    std::function<void(int, const GaussianCloud&)> gpuEval;
    if (onEval)
        gpuEval = [&](int iteration, const GaussianCloud& current) {
            seen = true;
            onEval(iteration, current);
        };
    StageTwoReport r = runOnDevice(
        options.device, "Stage II", cuda != nullptr,
        [&] { return cuda(cloud, samples, moving, gaussianCell, options, gpuEval, evalEvery); },
        [&] {
            if (seen && onRestart) onRestart(); // a fallback: the GPU run's evaluations are void
            return optimiseStageTwo(cloud, samples, moving, gaussianCell, options, onEval, evalEvery);
        },
        &used);
    r.device = used;
    return r;
}

} // namespace splatwarp
