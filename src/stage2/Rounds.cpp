#include "stage2/Rounds.h"

#include <algorithm>

#include "stage2/StageTwoDevice.h"

namespace splatwarp {
namespace {

/// Round `next` appended to `all` (RoundsReport::merged).
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

RoundsReport fitRounds(FitState& state, const SampleSet& samples, const StageTwoOptions& options, const RoundsPlan& plan)
{
    RoundsReport report;
    int done = 0;
    const int last = int(plan.iterations.size()) - 1;
    for (int round = 0; round <= last; ++round) {
        const int iterations = plan.iterations[std::size_t(round)];
        if (iterations > 0 || (round == last && plan.atLeastOne && report.rounds.empty())) {
            StageTwoOptions r = options;
            r.iterations = iterations;
            const int offset = done;
            std::function<void(int, const GaussianCloud&)> onEval;
            if (plan.onEval)
                onEval = [&](int iteration, const GaussianCloud& current) { plan.onEval(offset + iteration, current); };
            auto restart = [&] { // this round fell back to the CPU: its GPU evaluations are void
                if (plan.dropEvalsAfter) plan.dropEvalsAfter(offset);
            };
            report.rounds.push_back(
                runStageTwo(state.cloud, samples, state.moving, state.gaussianCell, r, onEval, plan.evalEvery, restart));
            appendRound(report.merged, report.rounds.back(), offset, report.rounds.size() == 1);
            done += iterations;
        }
        if (round < last && plan.between) plan.between(round);
    }
    return report;
}

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

} // namespace splatwarp
