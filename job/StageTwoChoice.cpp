#include "job/StageTwoChoice.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <unordered_map>

#include "job/ValidationResiduals.h"
#include "core/Progress.h"
#include "deform/CurveSplit.h"

namespace splatwarp {

namespace {

/// A coarse lattice over the validation points' warped positions.
class RegionLattice {
public:
    explicit RegionLattice(const std::vector<float>& points)
    {
        const PointLattice lattice(points, kChoiceRegions);
        std::copy_n(lattice.lo, 3, mLo);
        mSize = lattice.cell;
    }

    std::int64_t key(double x, double y, double z) const
    {
        const double v[3] = {x, y, z};
        std::int64_t k = 0;
        for (int a = 0; a < 3; ++a) k = k * 4096 + std::int64_t(std::floor((v[a] - mLo[a]) / mSize)) + 2048;
        return k;
    }

private:
    double mLo[3] = {0, 0, 0};
    double mSize = 0.0;
};

/// Per region of the lattice, the sum of each candidate's point scores there.
using RegionSums = std::unordered_map<std::int64_t, std::vector<double>>;

RegionSums regionSums(const RegionLattice& lattice, const std::vector<float>& x, const std::vector<std::vector<double>>& points)
{
    RegionSums sums;
    for (std::size_t j = 0; j < points[0].size(); ++j) {
        std::vector<double>& s = sums[lattice.key(x[3 * j], x[3 * j + 1], x[3 * j + 2])];
        s.resize(points.size(), 0.0);
        for (std::size_t c = 0; c < points.size(); ++c) s[c] += points[c][j];
    }
    return sums;
}

/// Per region, the candidate of `members` (a bit mask) that scores lowest there (ties: the earlier).
std::unordered_map<std::int64_t, std::size_t> regionWinners(const RegionSums& sums, unsigned members)
{
    std::unordered_map<std::int64_t, std::size_t> winners;
    for (const auto& [key, s] : sums) {
        std::size_t best = s.size();
        for (std::size_t c = 0; c < s.size(); ++c)
            if ((members >> c & 1u) && (best == s.size() || s[c] < s[best])) best = c;
        winners[key] = best;
    }
    return winners;
}

bool mixable(const std::vector<StageTwoCandidate>& candidates)
{
    for (const StageTwoCandidate& c : candidates)
        if (c.model->size() != candidates[0].model->size() || c.model->shDegree != candidates[0].model->shDegree)
            return false;
    return candidates.size() > 1 && candidates.size() < 8;
}

/// The Gaussians of the first candidate's regions taken from each region's winner.
GaussianCloud mixOf(const std::vector<StageTwoCandidate>& candidates, const RegionLattice& lattice,
                    const std::unordered_map<std::int64_t, std::size_t>& winners)
{
    const GaussianCloud& first = *candidates[0].model;
    GaussianCloud mix = first;
    for (std::size_t i = 0; i < first.size(); ++i) {
        const Vec3f m = first.mean(i);
        const auto it = winners.find(lattice.key(m.x, m.y, m.z));
        if (it != winners.end() && it->second != 0) mix.assign(i, *candidates[it->second].model, i);
    }
    return mix;
}

} // namespace

std::size_t firstLowest(const std::vector<double>& scores)
{
    return scores.empty() ? 0 : std::size_t(std::min_element(scores.begin(), scores.end()) - scores.begin());
}

double stillImprovingBy(const StageTwoReport& fit, double fitScore)
{
    if (fit.stoppedAt >= 0 || fit.heldOutChecks.empty()) return 0.0;
    const auto& [iteration, last] = fit.heldOutChecks.back();
    if (iteration <= 0 || !(last > 0) || !std::isfinite(fitScore)) return 0.0;
    const double fall = (last - fitScore) / last;
    return fall >= kStillImproving ? fall : 0.0;
}

Selection selectBest(const Judge& validation, const std::vector<const GaussianCloud*>& models)
{
    Selection s;
    for (const GaussianCloud* m : models) s.scores.push_back(validation.score(*m));
    s.best = firstLowest(s.scores);
    return s;
}

GaussianCloud chooseStageTwoModel(const Judge& validation, const std::vector<StageTwoCandidate>& candidates,
                                  bool sameGaussians, StageTwoChoice& report)
{
    const Stopwatch clock;
    std::vector<std::vector<double>> points;
    report.scores.clear();
    for (const StageTwoCandidate& c : candidates) {
        points.push_back(validation.pointScores(*c.model));
        report.scores.push_back(std::accumulate(points.back().begin(), points.back().end(), 0.0));
    }
    const std::size_t best = firstLowest(report.scores);
    GaussianCloud kept = *candidates[best].model;
    report.kept = candidates[best].name;
    report.mix = INFINITY;
    report.regionsWon.assign(candidates.size(), 0);
    if (sameGaussians && mixable(candidates)) {
        // Every mix of two or more candidates: a region's winner also changes its neighbours' points
        // (Gaussians reach across), so with more candidates the widest mix is not always the best.
        const std::vector<float>& x = validation.points().warped;
        const RegionLattice lattice(x);
        const RegionSums sums = regionSums(lattice, x, points);
        report.regions = sums.size();
        for (unsigned members = 3; members < (1u << candidates.size()); ++members) {
            if ((members & (members - 1)) == 0) continue; // a single candidate
            const auto winners = regionWinners(sums, members);
            GaussianCloud mix = mixOf(candidates, lattice, winners);
            const double score = validation.score(mix);
            if (!(score < report.mix)) continue;
            report.mix = score;
            report.mixOf.clear();
            for (std::size_t c = 0; c < candidates.size(); ++c)
                if (members >> c & 1u) report.mixOf += (report.mixOf.empty() ? "" : "+") + candidates[c].name;
            report.regionsWon.assign(candidates.size(), 0);
            for (const auto& [key, c] : winners) ++report.regionsWon[c];
            if (score < report.scores[best]) {
                kept = std::move(mix);
                report.kept = "mix";
            }
        }
    }
    report.ms = clock.ms();
    std::string line = "Stage II choice on validation points (opacity + colour error):";
    for (std::size_t c = 0; c < candidates.size(); ++c) line += msg(" ", candidates[c].name, " ", report.scores[c], ",");
    if (std::isfinite(report.mix)) line += msg(" mix of ", report.mixOf, " ", report.mix, " (", report.regions, " regions):");
    progress(msg(line, " keeping the ", report.kept));
    return kept;
}

CurveShiftChoice chooseCurveShift(const Judge& validation, const GaussianCloud& start, const std::vector<float>& curve,
                                  const std::vector<double>& shares)
{
    const Stopwatch clock;
    CurveShiftChoice c;
    double best = INFINITY;
    // The selector's rule (the first lowest), one shifted model at a time: holding all four would
    // add three models to the frame's peak memory.
    for (double share : shares) {
        GaussianCloud shifted = curveShifted(start, curve, share);
        c.scores.push_back(validation.score(shifted));
        if (c.scores.back() < best) {
            best = c.scores.back();
            c.share = share;
            c.model = std::move(shifted);
        }
    }
    c.ms = clock.ms();
    return c;
}

} // namespace splatwarp
