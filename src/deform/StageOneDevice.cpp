#include "deform/StageOneDevice.h"

#include "core/Progress.h"

namespace splatwarp {
namespace {

CudaSlot<StageOneEngineFactory> cudaSlot;

} // namespace

void registerStageOneCuda(StageOneEngineFactory cuda) { cudaSlot.set(cuda); }

StageOneUpdater::StageOneUpdater(const GaussianCloud& rest, const StageOneRig& rig, const DeformationGraph& graph,
                                 const StageOneOptions& options)
    : mRest(rest), mRig(rig), mGraph(graph), mOptions(options)
{
    const StageOneEngineFactory cuda = cudaSlot.get();
    mEngine = runOnDevice(
        options.device, "Stage I", cuda != nullptr, [&] { return cuda(rest, rig, graph.nodeCount(), options); },
        [] { return std::unique_ptr<StageOneEngine>(); });
}

StageOneUpdater::~StageOneUpdater() = default;

StageOneResult StageOneUpdater::apply(const NodeTransforms& transforms, const std::vector<std::uint8_t>& nodeMoving)
{
    if (mEngine) {
        const Stopwatch clock;
        checkStageOneInputs(mRest, mRig, mGraph, transforms, nodeMoving);
        try {
            StageOneResult r = mEngine->apply(nodeAffines(mGraph, transforms), nodeMoving);
            r.timings.updateMs = clock.ms();
            r.device = Device::Cuda;
            return r;
        } catch (const DeviceLimitError& e) {
            fallBackToCpu(mOptions.device, "Stage I", e);
            mEngine.reset();
        }
    }
    StageOneResult r = applyStageOneCpu(mRest, mRig, mGraph, transforms, nodeMoving, mOptions);
    r.device = Device::Cpu;
    return r;
}

} // namespace splatwarp
