#include "stage2/StageTwoLoop.h"

#include <cmath>
#include <limits>
#include <memory>

#include "core/Error.h"
#include "core/Progress.h"

namespace splatwarp {
namespace {

/// Best-iterate keeping (StageTwoOptions::keepBest): Adam on an L1 loss keeps stepping at the
/// optimum, so the lowest-energy iterate is returned instead of the last.
class BestIterate {
public:
    BestIterate(StageTwoSolver& solver, const StageTwoOptions& o) : mSolver(solver), mOptions(o) {}

    /// Record the energy of an iteration; a snapshot when it is the lowest so far.
    void offer(int iteration, double energy, StageTwoReport& report)
    {
        if (mOptions.keepBest && !(energy < report.bestEnergy)) return;
        report.bestEnergy = energy;
        report.bestIteration = iteration;
        if (mOptions.keepBest && iteration < mOptions.iterations) {
            mSolver.saveBest();
            mSaved = true;
        }
    }
    /// Put the best iterate back when it is not the current one.
    void restore(int lastIteration, const StageTwoReport& report)
    {
        if (!mSaved || report.bestIteration == lastIteration) return;
        mSolver.restoreBest();
        progress(msg("Stage II: kept iteration ", report.bestIteration, " (lowest energy ", report.bestEnergy, ")"));
    }

private:
    StageTwoSolver& mSolver;
    const StageTwoOptions& mOptions;
    bool mSaved = false;
};

/// Coverage for this iteration: the scheduled rebuild, or a forced one when a Gaussian left the
/// reach its coverage was built for (the learning-rate bound is an estimate; Adam can step
/// further), so a missed pair never silently changes the result.
void updateCoverage(StageTwoSolver& solver, const StageTwoOptions& o, int it, StageTwoReport& report)
{
    const bool scheduled = (it < o.iterations && it % o.rebuildEvery == 0) || it == 0;
    if (!scheduled && solver.coverageHolds()) return;
    solver.rebuildCoverage(it);
    ++report.coverageRebuilds;
    if (!scheduled) ++report.coverageForcedRebuilds;
}

void logEnergy(const StageTwoSolver& solver, const StageTwoEnergy& e, std::uint64_t pairs)
{
    progress(msg("Stage II iteration ", e.iteration, " (", solver.device(), "): energy ", e.total, " (colour ", e.color,
                 ", opacity ", e.opacity, ", boundary ", e.boundary, "), ", pairs, " pairs"));
}

void finishReport(const StageTwoSolver& solver, StageTwoReport& report)
{
    const StageTwoPhaseTimes t = solver.times();
    report.msCoverage = t.coverage;
    report.msForward = t.forward;
    report.msBackward = t.backward;
    report.msUpdate = t.update;
    report.coveragePairs = solver.coveragePairs();
    report.gpuPeakBytes = solver.peakDeviceBytes();
    report.device = solver.device();
}

} // namespace

StageTwoReport runStageTwoLoop(StageTwoSolver& solver, GaussianCloud& cloud, const StageTwoOptions& o,
                               const StageTwoEval& onEval, int evalEvery)
{
    Stopwatch total;
    StageTwoReport report;
    solver.describe(report);
    report.bestEnergy = std::numeric_limits<double>::infinity();
    BestIterate best(solver, o);
    std::unique_ptr<GaussianCloud> evalCloud; // onEval sees a copy; the caller's cloud is written at the end
    const int reportEvery = std::max(o.reportEvery, 1);
    int last = o.iterations;
    for (int it = 0; it <= o.iterations; ++it) {
        solver.prepare();
        updateCoverage(solver, o, it, report);
        std::uint64_t pairs = 0;
        const StageTwoEnergy e = solver.forward(it, pairs);
        if (!std::isfinite(e.total)) {
            if (it == 0) throw InputError("Stage II: the energy at the start is not finite (NaN/Inf in the model or the targets)");
            if (!o.keepBest) throw Error(msg("Stage II diverged at iteration ", it, " (energy not finite)"));
            progress(msg("Stage II: energy not finite at iteration ", it, "; stopping with the best iterate"));
            last = it;
            break;
        }
        best.offer(it, e.total, report);
        if (it % reportEvery == 0 || it == o.iterations) {
            report.energies.push_back(e);
            logEnergy(solver, e, pairs);
        }
        if (it == o.iterations) break; // final energy only
        report.pairsPerIteration.push_back(pairs);
        solver.backward();
        solver.step(it);
        if (onEval && evalEvery > 0 && (it + 1) % evalEvery == 0) {
            if (!evalCloud) evalCloud = std::make_unique<GaussianCloud>(cloud);
            solver.writeTo(*evalCloud);
            onEval(it + 1, *evalCloud);
        }
    }
    best.restore(last, report);
    solver.writeTo(cloud);
    finishReport(solver, report);
    report.msTotal = total.ms() + report.msSetup;
    return report;
}

} // namespace splatwarp
