#include "job/StageTwoRounds.h"

#include <cmath>

#include "core/Progress.h"

namespace splatwarp {

StageTwoReport fitInRounds(GaussianCloud& fitted, const SampleSet& samples, const std::vector<std::uint8_t>& stage1Moving,
                           const std::vector<std::int32_t>& gaussianCell, const StageTwoOptions& s2,
                           const DensifyJobOptions& d, const std::function<void(int, const GaussianCloud&)>& onEval,
                           int evalEvery, DensifyCounts& counts, const std::function<void(int)>& dropEvalsAfter)
{
    std::vector<std::uint8_t> moving = stage1Moving;
    std::vector<std::int32_t> cell = gaussianCell;
    FitState state{fitted, moving, cell};
    auto prune = [&] {
        if (d.pruneBelow > 0) counts.pruned += pruneMovingBelow(state, d.pruneBelow);
    };
    RoundsPlan plan{{s2.iterations}, true, {}, onEval, evalEvery, dropEvalsAfter};
    if (d.split) {
        const int first = int(std::lround(double(s2.iterations) * d.splitAfter));
        plan.iterations = {first, s2.iterations - first};
        plan.between = [&](int) {
            Stopwatch clock;
            prune();
            std::vector<std::size_t> stretched = stretchedGaussians(moving, cell, samples.cellGradient, d.splitStretch);
            if (d.maxSplits && stretched.size() > *d.maxSplits) stretched.resize(*d.maxSplits);
            counts.split += splitGaussians(state, stretched, keepMomentsSplit(d.splitOffset));
            counts.ms += clock.ms();
            progress(msg("Stage II: split ", counts.split, " Gaussians of cells stretched over ", d.splitStretch, " (",
                         fitted.size(), " Gaussians)"));
        };
    }
    StageTwoReport all = fitRounds(state, samples, s2, plan).merged;
    Stopwatch clock;
    prune();
    counts.ms += clock.ms();
    return all;
}

} // namespace splatwarp
