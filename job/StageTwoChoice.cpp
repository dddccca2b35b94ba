#include "StageTwoChoice.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <unordered_map>

#include "core/Progress.h"

namespace splatwarp {

namespace {

/// A coarse lattice over the validation points' warped positions.
class RegionLattice {
public:
    explicit RegionLattice(const std::vector<float>& points)
    {
        for (int a = 0; a < 3; ++a) {
            mLo[a] = INFINITY;
            double hi = -INFINITY;
            for (std::size_t j = a; j < points.size(); j += 3) {
                mLo[a] = std::min(mLo[a], double(points[j]));
                hi = std::max(hi, double(points[j]));
            }
            mSize = std::max(mSize, (hi - mLo[a]) / kChoiceRegions);
        }
        if (!(mSize > 0)) mSize = 1.0;
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

} // namespace

GaussianCloud chooseStageTwoModel(const Judge& validation, const GaussianCloud& start, GaussianCloud fit,
                                  bool sameGaussians, StageTwoChoice& report)
{
    const Stopwatch clock;
    const std::vector<double> a = validation.pointScores(start), b = validation.pointScores(fit);
    report.start = std::accumulate(a.begin(), a.end(), 0.0);
    report.fit = std::accumulate(b.begin(), b.end(), 0.0);
    report.mix = report.fit;
    GaussianCloud best = report.start < report.fit ? start : fit;
    report.kept = report.start < report.fit ? "start" : "fit";
    if (sameGaussians && start.size() == fit.size() && start.shDegree == fit.shDegree) {
        const std::vector<float>& x = validation.points().warped;
        const RegionLattice lattice(x);
        std::unordered_map<std::int64_t, double> gain; // sum over the region's points of start - fit
        for (std::size_t j = 0; j < a.size(); ++j) gain[lattice.key(x[3 * j], x[3 * j + 1], x[3 * j + 2])] += a[j] - b[j];
        report.regions = gain.size();
        for (const auto& [key, g] : gain) report.regionsFit += g > 0 ? 1 : 0;
        GaussianCloud mix = fit;
        for (std::size_t i = 0; i < start.size(); ++i) {
            const Vec3f m = start.mean(i);
            const auto it = gain.find(lattice.key(m.x, m.y, m.z));
            if (it != gain.end() && !(it->second > 0)) mix.assign(i, start, i); // the start won its region
        }
        report.mix = validation.score(mix);
        if (report.mix < std::min(report.start, report.fit)) {
            best = std::move(mix);
            report.kept = "mix";
        }
    }
    report.ms = clock.ms();
    progress(msg("Stage II choice on validation points (opacity + colour error): start ", report.start, ", fit ",
                 report.fit, ", mix ", report.mix, " (fit in ", report.regionsFit, " of ", report.regions,
                 " regions): keeping the ", report.kept));
    return best;
}

} // namespace splatwarp
