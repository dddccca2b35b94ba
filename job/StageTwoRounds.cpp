#include "job/StageTwoRounds.h"

#include <algorithm>
#include <cmath>

#include "core/Progress.h"
#include "stage2/StageTwoDevice.h"

namespace splatwarp {
namespace {

/// Round `next` appended to `all`: energies, pairs and iterations offset by the iterations before it,
/// counters and times summed, each round's device listed, the rest (best iterate, moving count,
/// device) of the last round.
void appendRound(StageTwoReport& all, const StageTwoReport& next, int offset, bool first)
{
    const StageTwoReport before = all;
    all = next;
    all.roundDevices = before.roundDevices;
    all.roundDevices.push_back(next.device);
    if (first) return;
    all.energies = before.energies;
    for (StageTwoEnergy e : next.energies) {
        e.iteration += offset;
        all.energies.push_back(e);
    }
    all.pairsPerIteration = before.pairsPerIteration;
    all.pairsPerIteration.insert(all.pairsPerIteration.end(), next.pairsPerIteration.begin(), next.pairsPerIteration.end());
    all.bestIteration += offset;
    if (next.stoppedAt >= 0) all.stoppedAt += offset;
    all.rejectedSteps += before.rejectedSteps;
    all.coverageRebuilds += before.coverageRebuilds;
    all.coverageForcedRebuilds += before.coverageForcedRebuilds;
    all.gpuPeakBytes = std::max(all.gpuPeakBytes, before.gpuPeakBytes);
    all.msSetup += before.msSetup;
    all.msCoverage += before.msCoverage;
    all.msForward += before.msForward;
    all.msBackward += before.msBackward;
    all.msRejected += before.msRejected;
    all.msUpdate += before.msUpdate;
    all.msTotal += before.msTotal;
}

} // namespace

std::string devicesName(const StageTwoReport& r)
{
    if (r.roundDevices.empty()) return deviceName(r.device);
    bool same = true;
    for (const Device d : r.roundDevices) same = same && d == r.roundDevices.front();
    if (same) return deviceName(r.roundDevices.front());
    std::string out;
    for (const Device d : r.roundDevices) out += (out.empty() ? "" : "+") + std::string(deviceName(d));
    return out;
}

StageTwoReport fitInRounds(GaussianCloud& fitted, const SampleSet& samples, const std::vector<std::uint8_t>& stage1Moving,
                           const std::vector<std::int32_t>& gaussianCell, const StageTwoOptions& s2,
                           const DensifyJobOptions& d, const std::function<void(int, const GaussianCloud&)>& onEval,
                           int evalEvery, DensifyCounts& counts, const std::function<void(int)>& dropEvalsAfter)
{
    std::vector<std::uint8_t> moving = stage1Moving;
    std::vector<std::int32_t> cell = gaussianCell;
    FitState dc{fitted, moving, cell};
    const int first = d.split ? int(std::lround(double(s2.iterations) * d.splitAfter)) : s2.iterations;
    StageTwoReport all;
    int done = 0;
    bool any = false;
    auto round = [&](int iterations) {
        StageTwoOptions r = s2;
        r.iterations = iterations;
        const int offset = done;
        auto shifted = [&](int iteration, const GaussianCloud& current) { onEval(offset + iteration, current); };
        auto restart = [&] { // this round fell back to the CPU: its GPU evaluations are void
            if (dropEvalsAfter) dropEvalsAfter(offset);
        };
        const StageTwoReport next = runStageTwo(fitted, samples, moving, cell, r,
                                                onEval ? std::function<void(int, const GaussianCloud&)>(shifted)
                                                       : std::function<void(int, const GaussianCloud&)>(),
                                                evalEvery, restart);
        appendRound(all, next, offset, !any);
        any = true;
        done += iterations;
    };
    auto prune = [&] {
        if (d.pruneBelow > 0) counts.pruned += pruneMovingBelow(dc, d.pruneBelow);
    };
    if (first > 0 || !d.split) round(first);
    if (d.split) {
        Stopwatch clock;
        prune();
        std::vector<std::size_t> stretched = stretchedGaussians(moving, cell, samples.cellGradient, d.splitStretch);
        if (d.maxSplits && stretched.size() > *d.maxSplits) stretched.resize(*d.maxSplits);
        counts.split += splitGaussians(dc, stretched, keepMomentsSplit(d.splitOffset));
        counts.ms += clock.ms();
        progress(msg("Stage II: split ", counts.split, " Gaussians of cells stretched over ", d.splitStretch, " (",
                     fitted.size(), " Gaussians)"));
        if (s2.iterations - first > 0 || !any) round(s2.iterations - first);
    }
    Stopwatch clock;
    prune();
    counts.ms += clock.ms();
    return all;
}


} // namespace splatwarp
