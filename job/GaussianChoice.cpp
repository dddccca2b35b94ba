#include "job/GaussianChoice.h"

#include <algorithm>

#include "job/ValidationResiduals.h"
#include "core/Progress.h"

namespace splatwarp {

namespace {

/// Gaussians some candidate holds another version of, heaviest (alpha s0 s1 s2) first.
std::vector<std::size_t> heaviestFirst(const std::vector<StageTwoCandidate>& candidates, const GaussianCloud& kept)
{
    std::vector<std::size_t> order;
    std::vector<double> mass(kept.size(), 0.0);
    for (std::size_t i = 0; i < kept.size(); ++i) {
        bool differs = false;
        for (const StageTwoCandidate& c : candidates) differs = differs || !kept.sameGaussian(i, *c.model, i);
        if (!differs) continue;
        const Vec3f s = kept.scale(i);
        mass[i] = double(kept.alpha(i)) * double(s.x) * double(s.y) * double(s.z);
        order.push_back(i);
    }
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return mass[a] > mass[b]; });
    return order;
}

/// The candidate whose version of Gaussian i lowers the score most, or none when none lowers it.
const GaussianCloud* bestFor(const ValidationResiduals& residuals, const std::vector<StageTwoCandidate>& candidates,
                             const GaussianCloud& kept, std::size_t i)
{
    std::vector<GaussianRef> ins;
    for (const StageTwoCandidate& c : candidates)
        if (!kept.sameGaussian(i, *c.model, i)) ins.push_back({c.model, i});
    std::vector<double> change(ins.size());
    residuals.changes({&kept, i}, ins, change.data());
    const GaussianCloud* best = nullptr;
    double bestChange = 0.0;
    for (std::size_t c = 0; c < ins.size(); ++c)
        if (change[c] < bestChange) {
            bestChange = change[c];
            best = ins[c].cloud;
        }
    return best;
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
    for (std::size_t i : order) {
        const GaussianCloud* best = bestFor(residuals, candidates, kept, i);
        if (!best) continue;
        residuals.apply({{&kept, i}}, {{best, i}});
        kept.assign(i, *best, i);
        ++report.swapped;
    }
    report.after = residuals.score();
    report.ms = clock.ms();
    progress(msg("Stage II choice per Gaussian: ", report.swapped, " of ", report.tried, " moving Gaussians swapped, validation ",
                 report.before, " -> ", report.after));
    return kept;
}

} // namespace splatwarp
