#include "job/GaussianChoice.h"

#include <algorithm>
#include <cstdint>

#include <tbb/parallel_invoke.h>

#include "job/ValidationResiduals.h"
#include "core/ParallelFor.h"
#include "core/Progress.h"

namespace splatwarp {

namespace {

/// The candidates' versions of Gaussian i that differ from kept's.
std::vector<GaussianRef> versionsOf(const std::vector<StageTwoCandidate>& candidates, const GaussianCloud& kept, std::size_t i)
{
    std::vector<GaussianRef> ins;
    for (const StageTwoCandidate& c : candidates)
        if (!kept.sameGaussian(i, *c.model, i)) ins.push_back({c.model, i});
    return ins;
}

/// Gaussians some candidate holds another version of, heaviest (alpha s0 s1 s2) first.
std::vector<std::size_t> heaviestFirst(const std::vector<StageTwoCandidate>& candidates, const GaussianCloud& kept)
{
    std::vector<std::size_t> order;
    std::vector<double> mass(kept.size(), 0.0);
    for (std::size_t i = 0; i < kept.size(); ++i) {
        if (versionsOf(candidates, kept, i).empty()) continue;
        mass[i] = kept.mass(i);
        order.push_back(i);
    }
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return mass[a] > mass[b]; });
    return order;
}

/// Gaussian i's pick: the candidate whose version lowers the score most on at least kMinChoicePoints
/// points (none when none does), and whether a version measured on fewer would have lowered it.
struct Pick {
    const GaussianCloud* best = nullptr;
    bool held = false;
};

Pick bestFor(const ValidationResiduals& residuals, const std::vector<StageTwoCandidate>& candidates,
             const GaussianCloud& kept, std::size_t i)
{
    const std::vector<GaussianRef> ins = versionsOf(candidates, kept, i);
    std::vector<std::vector<GaussianRef>> each;
    for (const GaussianRef& r : ins) each.push_back({r});
    std::vector<double> change(ins.size());
    std::vector<std::size_t> points(ins.size());
    residuals.changes({{&kept, i}}, each, change.data(), points.data());
    Pick pick;
    double bestChange = 0.0;
    bool lowersOnFewPoints = false;
    for (std::size_t c = 0; c < ins.size(); ++c) {
        if (!(change[c] < 0.0)) continue;
        if (points[c] < kMinChoicePoints) {
            lowersOnFewPoints = true;
        } else if (change[c] < bestChange) {
            bestChange = change[c];
            pick.best = ins[c].cloud;
        }
    }
    pick.held = !pick.best && lowersOnFewPoints;
    return pick;
}

/// Which side of one plane between buckets each pick reads: kBelow, kAbove or kBoth. A pick
/// reads only residuals in its buckets and a swap writes only within them, so picks of opposite
/// sides between two kBoth picks touch no common point and may run at once, each side in order:
/// the same picks, the same sums, in any schedule.
enum Side : std::uint8_t { kBelow, kAbove, kBoth };

std::vector<std::uint8_t> sidesOf(const ValidationResiduals& residuals, const std::vector<StageTwoCandidate>& candidates,
                                  const GaussianCloud& kept, const std::vector<std::size_t>& order, bool threaded)
{
    std::vector<BucketRange> reads(order.size());
    parallelFor(order.size(), 256, threaded, [&](std::size_t t) {
        reads[t] = residuals.reads({&kept, order[t]}, versionsOf(candidates, kept, order[t]));
    });
    int axis = 0; // the axis of most buckets, cut at the picks' median centre
    for (int a = 1; a < 3; ++a)
        if (residuals.bucketsAlong(a) > residuals.bucketsAlong(axis)) axis = a;
    std::vector<std::int64_t> centres;
    for (const BucketRange& r : reads)
        if (r.lo[axis] <= r.hi[axis]) centres.push_back(r.lo[axis] + r.hi[axis]);
    std::vector<std::uint8_t> sides(order.size(), kBelow); // a pick reading no bucket: any side
    if (centres.empty()) return sides;
    std::nth_element(centres.begin(), centres.begin() + std::ptrdiff_t(centres.size() / 2), centres.end());
    const std::int64_t plane = (centres[centres.size() / 2] + 1) / 2; // the first bucket above
    for (std::size_t t = 0; t < order.size(); ++t) {
        const BucketRange& r = reads[t];
        if (!(r.lo[axis] <= r.hi[axis])) continue;
        sides[t] = r.hi[axis] < plane ? kBelow : r.lo[axis] >= plane ? kAbove : kBoth;
    }
    return sides;
}

} // namespace

GaussianCloud chooseEachGaussian(const Judge& validation, const std::vector<StageTwoCandidate>& candidates,
                                 GaussianCloud kept, GaussianChoiceReport& report)
{
    const Stopwatch clock;
    ValidationResiduals residuals(validation, kept);
    report.before = residuals.score();
    const std::vector<std::size_t> order = heaviestFirst(candidates, kept);
    report.tried = order.size();
    const bool threaded = validation.points().features.threaded;
    const std::vector<std::uint8_t> sides = sidesOf(residuals, candidates, kept, order, threaded);
    std::size_t swapped[2] = {0, 0}, held[2] = {0, 0};
    const auto pick = [&](std::size_t t, int side) {
        const std::size_t i = order[t];
        const Pick p = bestFor(residuals, candidates, kept, i);
        held[side] += p.held;
        if (!p.best) return;
        residuals.apply({{&kept, i}}, {{p.best, i}});
        kept.assign(i, *p.best, i);
        ++swapped[side];
    };
    const auto runSide = [&](std::size_t begin, std::size_t end, std::uint8_t side) {
        for (std::size_t t = begin; t < end; ++t)
            if (sides[t] == side) pick(t, side);
    };
    constexpr std::size_t kShortRun = 4; // picks: shorter runs between kBoth picks go one at a time (16: 0.4 s slower on guitar)
    for (std::size_t t = 0; t < order.size();) {
        std::size_t end = t;
        while (end < order.size() && sides[end] != kBoth) ++end;
        if (threaded && end - t >= kShortRun)
            tbb::parallel_invoke([&] { runSide(t, end, kBelow); }, [&] { runSide(t, end, kAbove); });
        else
            for (std::size_t u = t; u < end; ++u) pick(u, sides[u]);
        if (end < order.size()) pick(end, 0);
        t = end + 1;
    }
    report.swapped = swapped[0] + swapped[1];
    report.held = held[0] + held[1];
    report.after = residuals.score();
    report.ms = clock.ms();
    progress(msg("Stage II choice per Gaussian: ", report.swapped, " of ", report.tried, " moving Gaussians swapped, validation ",
                 report.before, " -> ", report.after, "; ", report.held, " not swapped: measured on fewer than ", kMinChoicePoints,
                 " validation points"));
    return kept;
}

} // namespace splatwarp
