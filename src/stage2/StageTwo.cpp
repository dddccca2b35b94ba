#include "stage2/StageTwo.h"

#include "stage2/CpuSolver.h"
#include "stage2/StageTwoLoop.h"

namespace splatwarp {

StageTwoReport optimiseStageTwo(GaussianCloud& cloud, const SampleSet& samples, const std::vector<std::uint8_t>& moving,
                                const std::vector<std::int32_t>& gaussianCell, const StageTwoOptions& options,
                                const std::function<void(int, const GaussianCloud&)>& onEval, int evalEvery)
{
    const std::unique_ptr<StageTwoSolver> solver = makeCpuStageTwoSolver(cloud, samples, moving, gaussianCell, options);
    return runStageTwoLoop(*solver, cloud, options, onEval, evalEvery);
}

} // namespace splatwarp
