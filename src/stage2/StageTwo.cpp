#include "stage2/StageTwo.h"

#include "stage2/CpuSolver.h"
#include "stage2/StageTwoLoop.h"

namespace splatwarp {

std::size_t stageTwoBytesPerSample(int shDegree)
{
    const std::size_t stride = std::size_t(3 * (shDegree + 1) * (shDegree + 1));
    return 12 + 2 * 4 * stride + 2 * 4 + 12 + 4 + 8;
}

StageTwoReport optimiseStageTwo(GaussianCloud& cloud, const SampleSet& samples, const std::vector<std::uint8_t>& moving,
                                const std::vector<std::int32_t>& gaussianCell, const StageTwoOptions& options,
                                const std::function<void(int, const GaussianCloud&)>& onEval, int evalEvery)
{
    const std::unique_ptr<StageTwoSolver> solver = makeCpuStageTwoSolver(cloud, samples, moving, gaussianCell, options);
    return runStageTwoLoop(*solver, cloud, options, onEval, evalEvery);
}

} // namespace splatwarp
