#include "deform/StageOneDevice.h"

#include "core/Progress.h"

namespace splatwarp {
namespace {

CudaSlot<StageOneEngineFactory> cudaSlot;

} // namespace

void registerStageOneCuda(StageOneEngineFactory cuda) { cudaSlot.set(cuda); }

StageOneUpdater::StageOneUpdater(Device device, const GaussianCloud& rest, const StageOneRig& rig,
                                 const DeformationGraph& graph, const StageOneOptions& options)
    : mRequested(device), mRest(rest), mRig(rig), mGraph(graph), mOptions(options)
{
    const StageOneEngineFactory cuda = cudaSlot.get();
    mEngine = runOnDevice(
        device, "Stage I", cuda != nullptr, [&] { return cuda(rest, rig, graph.nodeCount(), options); },
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
            r.device = deviceName(Device::Cuda);
            return r;
        } catch (const DeviceMemoryError& e) {
            if (mRequested == Device::Cuda)
                throw DeviceMemoryError(msg(e.what(), " (--device cuda; --device auto would fall back to the CPU)"));
            progress(msg("Stage I: ", e.what(), "; running on the CPU instead"));
            mEngine.reset();
        }
    }
    StageOneResult r = applyStageOne(mRest, mRig, mGraph, transforms, nodeMoving, mOptions);
    r.device = deviceName(Device::Cpu);
    return r;
}

StageOneResult runStageOneOn(Device device, const GaussianCloud& rest, const Deformation& d, const StageOneOptions& o)
{
    const Stopwatch clock;
    const StageOneRig rig = prepareStageOne(rest, d.graph, o);
    const double rigMs = clock.ms();
    StageOneUpdater updater(device, rest, rig, d.graph, o);
    StageOneResult res = updater.apply(d.transforms, d.nodeMoving);
    res.timings.rigMs = rigMs;
    progress(msg("Stage I: ", res.movingCount, " of ", rest.size(), " Gaussians moved (", int(rigMs), " ms weights, ",
                 int(res.timings.updateMs), " ms update on ", res.device, ")"));
    return res;
}

StageOneResult runStageOne(const GaussianCloud& rest, const Deformation& d, const StageOneOptions& o)
{
    return runStageOneOn(Device::Cpu, rest, d, o);
}

} // namespace splatwarp
