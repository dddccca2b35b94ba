#include "stage2/StageTwoLoop.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <vector>

#include "core/Error.h"
#include "core/Progress.h"
#include "core/RunControl.h"

namespace splatwarp {
namespace {

/// Which iterate the run holds (StageTwoOptions::rejectSteps, keepBest). With step rejection:
/// the last accepted one, whose energy never rises; a step to a higher (or non-finite) energy is
/// undone and taken again shorter. Without: the lowest-energy iterate when keepBest, else the last.
/// With step rejection the rates' scale follows each step's outcome (stepFactor()), and Adam's
/// first step is shortened beforehand (shortensFirstStep()). Measured against the old rule (halve
/// after a rejection, x1.25 after each accepted step): the demo rejected 0 steps of 50 instead of
/// 13, train-1000 1-2 instead of 13-14, at judged errors within a few percent
/// (docs/lab/stage2-iterations.md, "A step rule from the energy's slope").
class IterateKeeper {
public:
    /// An accepted step's factor lies in [0.5, kRegrowth] (the scale capped at 1), a rejected
    /// one's in [kLeastFactor, 0.5].
    static constexpr double kRegrowth = 1.25, kLeastFactor = 1.0 / 16.0;
    /// After an accepted step the rates aim at kOvershoot times the parabola's best length, which
    /// settles where the energy falls by about a quarter of the first-order decrease. At 1 (the
    /// parabola's best) train-1000 fit 5-9% worse: Adam's averaged steps gain from longer ones.
    static constexpr double kOvershoot = 1.5;
    /// Adam's first step moves every parameter by its whole rate. It may promise at most this share
    /// of the energy: train-1000 descended at 3.5% and climbed at 9%, the demo descended at 39%.
    static constexpr double kFirstStepShare = 0.03;

    /// @brief The factor on the rates after a step, from the energy's actual decrease and the
    ///        step's first-order (predicted) one. On the parabola through the energy before, its
    ///        slope along the step and the energy after, the best length is t = 1 / (2 (1 - r)),
    ///        r = actual / predicted, in units of the step taken. Rejected: the step is taken again
    ///        at t (the same direction: the parabola's best). Accepted: the next step aims at
    ///        kOvershoot t. A non-finite energy or a step that was no descent to first order:
    ///        x0.5 rejected, kRegrowth accepted.
    static double stepFactor(double actual, double predicted, bool accepted)
    {
        const double r = actual / predicted;
        if (!(predicted > 0) || !std::isfinite(r)) return accepted ? kRegrowth : 0.5;
        const double t = r < 1 ? 1.0 / (2.0 * (1.0 - r)) : kRegrowth;
        return accepted ? std::clamp(kOvershoot * t, 0.5, kRegrowth) : std::clamp(t, kLeastFactor, 0.5);
    }

    IterateKeeper(StageTwoSolver& solver, const StageTwoOptions& o) : mSolver(solver), mOptions(o) {}

    /// Judge the iterate just evaluated; false when it was rejected (the solver is then back at
    /// the accepted iterate, with its gradient, ready to step again).
    bool judge(int iteration, double energy, StageTwoReport& report)
    {
        const bool accepted = mOptions.rejectSteps ? judgeWithRejection(iteration, energy, report)
                                                   : judgeWithoutRejection(iteration, energy, report);
        mHeld.push_back(mOptions.rejectSteps ? report.bestEnergy : energy);
        return accepted;
    }
    /// The next step from the iterate held.
    StageTwoStep nextStep(int iteration) const { return {iteration, mAccepted, mRateScale}; }
    /// @brief Whether the step just taken was Adam's first and promised more than
    ///        kFirstStepShare of the energy: the rates are then scaled to promise that share, and
    ///        the caller takes the step again from the kept iterate.
    bool shortensFirstStep(double predicted, double energy)
    {
        if (!mOptions.rejectSteps || mAccepted != 1 || mRejectedInARow > 0 || !(predicted > kFirstStepShare * energy))
            return false;
        mRateScale *= float(kFirstStepShare * energy / predicted);
        return true;
    }
    /// The first-order decrease of the step just taken (StageTwoSolver::step()).
    void stepped(double predicted) { mPredicted = predicted; }
    /// Why the run should stop now (StageTwoOptions::stallStop, stallTolerance); null: go on.
    const char* stalled() const
    {
        // Before the first accepted step the limit doubles: Adam's first step moves every parameter
        // by its whole rate, and from a Stage I start it may descend only at 2^-6 of the rates
        // (train-1000 bend --cells 80: energy 68.8 at the start, 69.1 at 2^-5, accepted at 2^-6).
        const int limit = mAccepted > 1 ? mOptions.stallStop : 2 * mOptions.stallStop; // iteration 0 counts as one
        if (mOptions.stallStop > 0 && mRejectedInARow >= limit) return "steps rejected in a row";
        const std::size_t w = std::size_t(std::max(mOptions.stallWindow, 1)), n = mHeld.size();
        if (mOptions.stallTolerance > 0 && n > w &&
            !(mHeld[n - 1 - w] - mHeld[n - 1] >= double(mOptions.stallTolerance) * mHeld[n - 1 - w]))
            return "the energy stalled";
        return nullptr;
    }
    /// Put the kept iterate back when the run ends on another (keepBest without rejection).
    void finish(int lastIteration, const StageTwoReport& report)
    {
        if (mOptions.rejectSteps || !mSaved || report.bestIteration == lastIteration) return;
        mSolver.restoreIterate();
        progress(msg("Stage II: kept iteration ", report.bestIteration, " (lowest energy ", report.bestEnergy, ")"));
    }

private:
    bool judgeWithRejection(int iteration, double energy, StageTwoReport& report)
    {
        const double actual = report.bestEnergy - energy; // -inf at iteration 0
        if (!(energy <= report.bestEnergy)) { // a climb or a non-finite energy (never at iteration 0: best is +inf there)
            mSolver.restoreIterate();
            mRateScale *= float(stepFactor(actual, mPredicted, false));
            ++mRejectedInARow;
            ++report.rejectedSteps;
            return false;
        }
        ++mAccepted;
        mRejectedInARow = 0;
        if (iteration > 0) mRateScale = std::min(1.0f, float(stepFactor(actual, mPredicted, true)) * mRateScale);
        record(iteration, energy, report);
        save();
        return true;
    }
    bool judgeWithoutRejection(int iteration, double energy, StageTwoReport& report)
    {
        ++mAccepted;
        if (mOptions.keepBest && !(energy < report.bestEnergy)) return true;
        record(iteration, energy, report);
        if (mOptions.keepBest && iteration < mOptions.iterations) save();
        return true;
    }
    void record(int iteration, double energy, StageTwoReport& report) const
    {
        report.bestEnergy = energy;
        report.bestIteration = iteration;
    }
    void save()
    {
        mSolver.saveIterate();
        mSaved = true;
    }

    StageTwoSolver& mSolver;
    const StageTwoOptions& mOptions;
    std::vector<double> mHeld; ///< energy of the iterate held after each iteration
    bool mSaved = false;
    int mAccepted = 0, mRejectedInARow = 0;
    float mRateScale = 1.0f;
    double mPredicted = 0; ///< the last step's first-order decrease
};

/// Coverage for this iteration: built at the start, rebuilt when a Gaussian has left the reach
/// it was built for (so a missed pair never silently changes the result) or on the optional
/// schedule. Gaussians move far less than the learning-rate bound assumes: on the demo a reach of
/// 10 steps held for all 100 iterations.
void updateCoverage(StageTwoSolver& solver, const StageTwoOptions& o, int it, StageTwoReport& report)
{
    const bool scheduled = it == 0 || (o.rebuildEvery > 0 && it < o.iterations && it % o.rebuildEvery == 0);
    if (!scheduled && solver.coverageHolds()) return;
    solver.rebuildCoverage(it, !scheduled);
    ++report.coverageRebuilds;
    if (!scheduled) ++report.coverageForcedRebuilds;
}

/// StageTwoOptions::heldOutStop: scores the start, the held iterate after `early` steps and then
/// every `every` iterations, and says why the run should stop (a non-finite score stops too).
class HeldOutCheck {
public:
    HeldOutCheck(const StageTwoOptions::HeldOutStop& stop, int iterations) : mStop(stop), mIterations(iterations) {}

    /// Whether iteration `it` is scored: 0 (the start, the reference of the next two checks),
    /// `early` and every `every`-th.
    bool due(int it) const { return mStop.on() && (it % mStop.every == 0 || isEarly(it)); }
    /// Score the model held at `it` (a due iteration): why the run stops there, or nullptr.
    const char* verdict(int it, const GaussianCloud& held, StageTwoReport& report)
    {
        const double score = mStop.score(held);
        report.heldOutChecks.emplace_back(it, score);
        progress(msg("Stage II iteration ", it, ": validation score ", score));
        const bool againstStart = isEarly(it) || it == mStop.every;
        const char* why = nullptr;
        if (!(score <= (againstStart ? mStart : mLast) * (1.0 + (againstStart ? mStop.riseFromStart : mStop.rise))))
            why = "the validation score rose";
        else if (it > mStop.every && !backByTheEnd(it, score))
            why = "the validation score stays above the start's";
        if (it == 0) mStart = score;
        mLast = score;
        return why;
    }

private:
    bool isEarly(int it) const { return mStop.early > 0 && it == mStop.early && mStop.early < mStop.every; }
    /// Whether a fit scoring worse than its start would, at the pace since the last check, come
    /// back below the start's score by the last iteration.
    bool backByTheEnd(int it, double score) const
    {
        if (score <= mStart) return true;
        const double pace = (score - mLast) / mStop.every;
        return score + pace * (mIterations - it) <= mStart;
    }

    const StageTwoOptions::HeldOutStop& mStop;
    int mIterations;
    double mStart = std::numeric_limits<double>::infinity();
    double mLast = std::numeric_limits<double>::infinity();
};

/// Whether a non-finite energy ends the run (with the best iterate). At the start it is bad input;
/// later, with step rejection, just a rejected step; without, the end (keepBest) or an error.
bool stopsOnNonFinite(const StageTwoEnergy& e, int it, const StageTwoOptions& o)
{
    if (std::isfinite(e.total) || (it > 0 && o.rejectSteps)) return false;
    if (it == 0) throw InputError("Stage II: the energy at the start is not finite (NaN/Inf in the model or the targets)");
    if (!o.keepBest) throw Error(msg("Stage II diverged at iteration ", it, " (energy not finite)"));
    progress(msg("Stage II: energy not finite at iteration ", it, "; stopping with the best iterate"));
    return true;
}

/// One step from the iterate held; Adam's first step is taken again shorter when it promises too
/// much (from the kept iterate: its moments too).
void takeStep(StageTwoSolver& solver, IterateKeeper& keeper, int it, double energy)
{
    double predicted = solver.step(keeper.nextStep(it));
    if (keeper.shortensFirstStep(predicted, energy)) {
        solver.restoreIterate();
        predicted = solver.step(keeper.nextStep(it));
    }
    keeper.stepped(predicted);
}

void logEnergy(const StageTwoSolver& solver, const StageTwoEnergy& e, std::uint64_t pairs)
{
    progress(msg("Stage II iteration ", e.iteration, " (", deviceName(solver.device()), "): energy ", e.total, " (colour ", e.color,
                 ", opacity ", e.opacity, ", boundary ", e.boundary, "), ", pairs, " pairs",
                 e.rejected ? "; step rejected, taken again shorter" : ""));
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
    IterateKeeper keeper(solver, o);
    std::unique_ptr<GaussianCloud> evalCloud; // onEval and heldOut see a copy; the caller's cloud is written at the end
    const auto current = [&]() -> const GaussianCloud& {
        if (!evalCloud) evalCloud = std::make_unique<GaussianCloud>(cloud);
        solver.writeTo(*evalCloud);
        return *evalCloud;
    };
    HeldOutCheck heldOut(o.heldOutStop, o.iterations);
    const int reportEvery = std::max(o.reportEvery, 1);
    int last = o.iterations;
    for (int it = 0; it <= o.iterations; ++it) {
        solver.prepare();
        updateCoverage(solver, o, it, report);
        std::uint64_t pairs = 0;
        const StageTwoPhaseTimes before = solver.times();
        StageTwoEnergy e = solver.forward(it, pairs);
        if (stopsOnNonFinite(e, it, o)) {
            last = it;
            break;
        }
        e.rejected = !keeper.judge(it, e.total, report);
        if (e.rejected) {
            const StageTwoPhaseTimes after = solver.times();
            report.msRejected += after.forward - before.forward + after.backward - before.backward;
        }
        if (it % reportEvery == 0 || it == o.iterations || e.rejected) {
            report.energies.push_back(e);
            logEnergy(solver, e, pairs);
        }
        if (it == o.iterations) break; // final energy only
        const char* why = keeper.stalled();
        // The start is scored as given (the keep scores the same bytes again, and its judge
        // remembers them), later iterates as the solver holds them.
        if (!why && heldOut.due(it)) why = heldOut.verdict(it, it == 0 ? cloud : current(), report);
        if (why) {
            progress(msg("Stage II: stopping at iteration ", it, " (", why, ")"));
            report.stoppedAt = it;
            report.stopReason = why;
            last = it;
            break;
        }
        report.pairsPerIteration.push_back(pairs);
        if (!e.rejected) solver.backward(); // a rejected step is taken again with the kept gradient
        takeStep(solver, keeper, it, report.bestEnergy);
        reportProgress("Stage II", it + 1, o.iterations); // a cancel stops here, within one iteration
        if (onEval && evalEvery > 0 && (it + 1) % evalEvery == 0) onEval(it + 1, current());
    }
    keeper.finish(last, report);
    solver.writeTo(cloud);
    finishReport(solver, report);
    report.msTotal = total.ms() + report.msSetup;
    return report;
}

} // namespace splatwarp
