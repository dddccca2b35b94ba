#include "io/CloudStats.h"

#include <algorithm>
#include "core/Error.h"
#include "core/Outliers.h"
#include <cmath>
#include <limits>
#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>
#include <vector>

namespace splatwarp {

namespace {

// Partial result of the per-Gaussian reduction (parallel_reduce body).
struct StatsOp {
    const GaussianCloud& g;
    double lo[3], hi[3];
    double opMin, opMax, opSum = 0;
    std::size_t opCount = 0;
    double qMin, qMax;
    double sMin, sMax;
    std::size_t invalid = 0;

    explicit StatsOp(const GaussianCloud& cloud) : g(cloud) { clear(); }
    StatsOp(StatsOp& o, tbb::split) : g(o.g) { clear(); }

    void clear()
    {
        const double inf = std::numeric_limits<double>::infinity();
        for (int a = 0; a < 3; ++a) lo[a] = inf, hi[a] = -inf;
        opMin = qMin = sMin = inf;
        opMax = qMax = sMax = -inf;
    }

    void operator()(const tbb::blocked_range<std::size_t>& r)
    {
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
            bool centreOk = true;
            for (int a = 0; a < 3; ++a) centreOk = centreOk && std::isfinite(g.means[3 * i + a]);
            if (centreOk)
                for (int a = 0; a < 3; ++a) {
                    lo[a] = std::min(lo[a], double(g.means[3 * i + a]));
                    hi[a] = std::max(hi[a], double(g.means[3 * i + a]));
                }
            const double o = g.opacities[i];
            if (std::isfinite(o)) {
                const double alpha = 1.0 / (1.0 + std::exp(-o));
                opMin = std::min(opMin, alpha);
                opMax = std::max(opMax, alpha);
                opSum += alpha;
                ++opCount;
            }
            double q2 = 0;
            for (int a = 0; a < 4; ++a) q2 += double(g.rotations[4 * i + a]) * g.rotations[4 * i + a];
            if (std::isfinite(q2)) {
                qMin = std::min(qMin, std::sqrt(q2));
                qMax = std::max(qMax, std::sqrt(q2));
            }
            for (int a = 0; a < 3; ++a) {
                const double s = std::exp(double(g.logScales[3 * i + a]));
                if (!std::isfinite(g.logScales[3 * i + a])) continue;
                sMin = std::min(sMin, s);
                sMax = std::max(sMax, s);
            }
            const auto countBad = [&](const float* v, std::size_t n) {
                for (std::size_t j = 0; j < n; ++j) invalid += std::isfinite(v[j]) ? 0 : 1;
            };
            countBad(&g.means[3 * i], 3);
            countBad(&g.rotations[4 * i], 4);
            countBad(&g.logScales[3 * i], 3);
            countBad(&g.opacities[i], 1);
            countBad(g.shOf(i), std::size_t(g.shStride()));
        }
    }

    void join(const StatsOp& o)
    {
        for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], o.lo[a]), hi[a] = std::max(hi[a], o.hi[a]);
        opMin = std::min(opMin, o.opMin);
        opMax = std::max(opMax, o.opMax);
        opSum += o.opSum;
        opCount += o.opCount;
        qMin = std::min(qMin, o.qMin);
        qMax = std::max(qMax, o.qMax);
        sMin = std::min(sMin, o.sMin);
        sMax = std::max(sMax, o.sMax);
        invalid += o.invalid;
    }
};

// Replace the +-inf "nothing seen" identity by 0.
double orZero(double v) { return std::isfinite(v) ? v : 0.0; }

} // namespace

CloudStats computeCloudStats(const GaussianCloud& g, bool threaded)
{
    CloudStats s;
    s.count = g.size();
    s.shDegree = g.shDegree;
    StatsOp op(g);
    const tbb::blocked_range<std::size_t> all(0, g.size(), 4096);
    if (threaded) tbb::parallel_reduce(all, op);
    else op(all);

    s.bboxMin = Vec3d(orZero(op.lo[0]), orZero(op.lo[1]), orZero(op.lo[2]));
    s.bboxMax = Vec3d(orZero(op.hi[0]), orZero(op.hi[1]), orZero(op.hi[2]));
    s.opacityMin = orZero(op.opMin);
    s.opacityMax = orZero(op.opMax);
    s.opacityMean = op.opCount ? op.opSum / double(op.opCount) : 0.0;
    s.quatNormMin = orZero(op.qMin);
    s.quatNormMax = orZero(op.qMax);
    s.scaleMin = orZero(op.sMin);
    s.scaleMax = orZero(op.sMax);
    s.invalidValues = op.invalid;

    // Median of the finite activated scales (lower median for an even count).
    std::vector<float> logs;
    logs.reserve(g.logScales.size());
    for (float v : g.logScales)
        if (std::isfinite(v)) logs.push_back(v);
    if (!logs.empty()) {
        auto mid = logs.begin() + std::ptrdiff_t((logs.size() - 1) / 2);
        std::nth_element(logs.begin(), mid, logs.end());
        s.scaleMedian = std::exp(double(*mid)); // exp is monotonic: median of exp = exp of median
    }
    return s;
}

std::vector<CloudWarning> outlierWarnings(const GaussianCloud& g)
{
    const Outliers f = findOutliers(g);
    std::vector<CloudWarning> out;
    if (f.farCount)
        out.push_back({"far-centres", f.farCount,
                       msg(f.farCount, " Gaussians lie far from the rest (their centres more than ", f.bulkSize,
                           " units outside the box of the central 98%): the model's box is ",
                           std::round(10.0 * f.boxRatio) / 10.0, "x that size, and deform spends its --cells on it "
                           "and reads a spec's \"bbox\" units in it (`convert --drop-outliers` drops them)")});
    const std::string wider = msg(" wider than half the bulk (a standard deviation over ", kGiantSigma * f.bulkSize,
                                  " units, the largest ", f.largestSigma, ")");
    if (2 * f.giantCount > g.size()) // not a few stray ones: the file's scales are likely not what they say
        out.push_back({"giant-gaussians", f.giantCount,
                       msg(f.giantCount, " of the ", g.size(), " Gaussians are", wider,
                           ": a file whose writer stored linear scales where log scales belong looks like this "
                           "(graphdeco's scale_* are logs); each reaches most of the model, which makes deform "
                           "slow and may pass --max-memory")});
    else if (f.giantCount)
        out.push_back({"giant-gaussians", f.giantCount,
                       msg(f.giantCount, " Gaussians are", wider,
                           ": their reach sets the box deform spends its --cells on (`convert --drop-outliers` "
                           "drops them)")});
    return out;
}

std::vector<CloudWarning> cloudWarnings(const GaussianCloud& g, const CloudStats& stats)
{
    std::vector<CloudWarning> out;
    if (g.empty()) // its statistics are zeros, not measurements
        return {{"no-gaussians", 0, "the file holds no Gaussians (other commands refuse it; the statistics above are empty)"}};
    const auto add = [&](const char* kind, std::size_t count, const std::string& text) {
        if (count) out.push_back({kind, count, text});
    };
    add("non-finite", stats.invalidValues,
        msg(stats.invalidValues, " NaN/Inf values (other commands refuse the file; --drop-invalid drops those Gaussians)"));
    Vec3d span = stats.bboxMax - stats.bboxMin;
    const double extent = std::max(span.x, std::max(span.y, span.z));
    std::size_t offUnit = 0, nearZero = 0, huge = 0, tiny = 0;
    for (std::size_t i = 0; i < g.size(); ++i) {
        double q2 = 0;
        for (int a = 0; a < 4; ++a) q2 += double(g.rotations[4 * i + a]) * g.rotations[4 * i + a];
        const double q = std::sqrt(q2);
        offUnit += std::isfinite(q) && std::fabs(q - 1.0) > 0.01 ? 1 : 0;
        nearZero += q < 1e-6 ? 1 : 0;
        const float* ls = &g.logScales[3 * i];
        const double s = std::exp(double(std::max(ls[0], std::max(ls[1], ls[2]))));
        huge += extent > 0 && s > 10.0 * extent ? 1 : 0;
        tiny += extent > 0 && s < 1e-6 * extent ? 1 : 0;
    }
    add("unnormalised-quaternions", offUnit,
        msg(offUnit, " quaternions are not unit length (norm ", stats.quatNormMin, " .. ", stats.quatNormMax,
            "); they are normalised on use", nearZero ? msg(", but ", nearZero, " are near zero and have no defined rotation") : ""));
    add("extreme-scales", huge + tiny,
        msg(huge, " Gaussians are larger than 10x the centres' extent (", extent, ") and ", tiny,
            " smaller than 1e-6 of it (largest scale ", stats.scaleMax, ", smallest ", stats.scaleMin, ")"));
    for (CloudWarning& w : outlierWarnings(g)) out.push_back(std::move(w));
    const double far = std::max(std::max(std::fabs(stats.bboxMin.x), std::fabs(stats.bboxMax.x)),
                                std::max(std::max(std::fabs(stats.bboxMin.y), std::fabs(stats.bboxMax.y)),
                                         std::max(std::fabs(stats.bboxMin.z), std::fabs(stats.bboxMax.z))));
    add("extreme-extent", far > 1e6 ? g.size() : 0,
        msg("centres reach ", far, " units from the origin: float32 resolves only ", far * 6e-8,
            " units there (recentre the model)"));
    return out;
}

} // namespace splatwarp
