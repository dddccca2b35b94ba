#pragma once
/// @file StageOneDevice.h
/// @brief The Stage I per-Gaussian update on the chosen device. Stage I has three parts: the rig
///        (prepareStageOne(), once per model and graph), the update (StageOneUpdater::apply(), on
///        options.device) and its two implementations, the CPU applyStageOneCpu() and a
///        device-resident StageOneEngine the CUDA kernels register at start-up (the core library
///        cannot link them). The engine uploads the rest model and rig once; each update uploads
///        only the node transforms ([J] affine maps) and downloads the result.
#include <cstdint>
#include <memory>
#include <vector>

#include "core/Device.h"
#include "deform/StageOne.h"

namespace splatwarp {

/// @brief A Stage I update bound to one rest model and rig, resident on a device.
class StageOneEngine {
public:
    virtual ~StageOneEngine() = default;
    /// @brief Deformed model for node transforms affines [J] (nodeAffines()) and moving flags [J];
    ///        fills deformed, moving and movingCount (not timings or device).
    /// @throws DeviceMemoryError when a buffer does not fit; Error for other device failures
    virtual StageOneResult apply(const std::vector<NodeAffine>& affines, const std::vector<std::uint8_t>& nodeMoving) = 0;
};

/// @brief Builds an engine for a rest model and its rig (the rig's node indices are < nodeCount).
using StageOneEngineFactory = std::unique_ptr<StageOneEngine> (*)(const GaussianCloud& rest, const StageOneRig& rig,
                                                                   std::size_t nodeCount, const StageOneOptions& options);

/// @brief Register the CUDA Stage I engine (nullptr unregisters). Called by cuda::registerBackends().
void registerStageOneCuda(StageOneEngineFactory cuda);

/// @brief Stage I updates of one rest model and rig on options.device, as many as wanted (the
///        bench times each). When the GPU cannot take it under Auto (DeviceLimitError, creating
///        the engine or updating) the update runs on the CPU from then on, with a progress message;
///        under Cuda the DeviceLimitError propagates.
/// @note  rest, rig and graph are referenced, not copied: they must outlive the updater.
class StageOneUpdater {
public:
    /// @throws InputError when Cuda was asked and no CUDA engine is registered
    StageOneUpdater(const GaussianCloud& rest, const StageOneRig& rig, const DeformationGraph& graph,
                    const StageOneOptions& options = {});
    ~StageOneUpdater();
    StageOneUpdater(const StageOneUpdater&) = delete;
    StageOneUpdater& operator=(const StageOneUpdater&) = delete;

    /// @brief Same result as applyStageOneCpu(); result.device says which device ran.
    StageOneResult apply(const NodeTransforms& transforms, const std::vector<std::uint8_t>& nodeMoving);
    /// @brief The device the next update runs on.
    Device device() const { return mEngine ? Device::Cuda : Device::Cpu; }

private:
    const GaussianCloud& mRest;
    const StageOneRig& mRig;
    const DeformationGraph& mGraph;
    StageOneOptions mOptions;
    std::unique_ptr<StageOneEngine> mEngine; ///< null: the CPU
};

} // namespace splatwarp
