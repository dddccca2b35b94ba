#pragma once
/// @file StageTwoDevice.h
/// @brief Stage II on the chosen device: the CPU optimiser (StageTwo.h) or the CUDA one the
///        kernels register at start-up (the core library cannot link them).
#include "core/Device.h"
#include "stage2/StageTwo.h"

namespace splatwarp {

/// @brief Signature of a Stage II implementation (that of optimiseStageTwo()). A GPU
///        implementation must leave the cloud untouched when it throws, so the run can be
///        repeated on the CPU.
using StageTwoFunction = StageTwoReport (*)(GaussianCloud&, const SampleSet&, const std::vector<std::uint8_t>&,
                                            const std::vector<std::int32_t>&, const StageTwoOptions&,
                                            const std::function<void(int, const GaussianCloud&)>&, int);

/// @brief Register the CUDA Stage II (nullptr unregisters). Called by cuda::registerBackends().
void registerStageTwoCuda(StageTwoFunction cuda);

/// @brief Run Stage II (same arguments and results as optimiseStageTwo()) on a device.
///        options.device says where; when the GPU cannot take the run under Auto (DeviceLimitError:
///        out of memory, counts past its indices) it repeats on the CPU with a progress message,
///        under Cuda the DeviceLimitError propagates. report.device says which device ran.
/// @param onRestart  called when a GPU run that onEval already saw iterations of falls back: the
///                   CPU run starts again at iteration 0, so the caller drops what onEval recorded
///                   in this call (else the curve holds both runs' iterations)
/// @throws InputError when Cuda was asked and no CUDA Stage II is registered
StageTwoReport runStageTwo(GaussianCloud& cloud, const SampleSet& samples,
                           const std::vector<std::uint8_t>& moving, const std::vector<std::int32_t>& gaussianCell,
                           const StageTwoOptions& options,
                           const std::function<void(int, const GaussianCloud&)>& onEval = {}, int evalEvery = 0,
                           const std::function<void()>& onRestart = {});

} // namespace splatwarp
