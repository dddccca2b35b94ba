#include "core/Outliers.h"

#include <algorithm>
#include <cmath>

namespace splatwarp {

namespace {

bool finiteCentre(const GaussianCloud& g, std::size_t i)
{
    return std::isfinite(g.means[3 * i]) && std::isfinite(g.means[3 * i + 1]) && std::isfinite(g.means[3 * i + 2]);
}

/// The largest standard deviation of Gaussian i; 0 where no log-scale is finite.
double largestSigma(const GaussianCloud& g, std::size_t i)
{
    double s = 0;
    for (int a = 0; a < 3; ++a) {
        const double v = std::exp(double(g.logScales[3 * i + std::size_t(a)]));
        if (std::isfinite(v)) s = std::max(s, v);
    }
    return s;
}

} // namespace

double centreQuantile(const GaussianCloud& g, int axis, double q)
{
    std::vector<float> v;
    v.reserve(g.size());
    for (std::size_t i = 0; i < g.size(); ++i)
        if (finiteCentre(g, i)) v.push_back(g.means[3 * i + std::size_t(axis)]);
    if (v.empty()) return 0.0;
    const std::size_t k = std::min(v.size() - 1, std::size_t(std::floor(q * double(v.size() - 1) + 0.5)));
    std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(k), v.end());
    return v[k];
}

std::vector<std::uint8_t> Outliers::either() const
{
    std::vector<std::uint8_t> out(far.size(), 0);
    for (std::size_t i = 0; i < far.size(); ++i) out[i] = far[i] || giant[i] ? 1 : 0;
    return out;
}

Outliers findOutliers(const GaussianCloud& g)
{
    Outliers f;
    f.far.assign(g.size(), 0);
    f.giant.assign(g.size(), 0);
    for (int a = 0; a < 3; ++a) {
        f.bulkLo[a] = centreQuantile(g, a, kBulkQuantile);
        f.bulkHi[a] = centreQuantile(g, a, 1.0 - kBulkQuantile);
        f.bulkSize = std::max(f.bulkSize, f.bulkHi[a] - f.bulkLo[a]);
    }
    if (!(f.bulkSize > 0)) return f;
    Vec3d lo = f.bulkLo, hi = f.bulkHi;
    for (std::size_t i = 0; i < g.size(); ++i) {
        const double sigma = largestSigma(g, i);
        f.largestSigma = std::max(f.largestSigma, sigma);
        f.giant[i] = sigma > kGiantSigma * f.bulkSize ? 1 : 0;
        f.giantCount += f.giant[i];
        if (!finiteCentre(g, i)) continue;
        bool far = false;
        for (int a = 0; a < 3; ++a) {
            const double p = g.means[3 * i + std::size_t(a)];
            lo[a] = std::min(lo[a], p);
            hi[a] = std::max(hi[a], p);
            far = far || p < f.bulkLo[a] - f.bulkSize || p > f.bulkHi[a] + f.bulkSize;
        }
        f.far[i] = far ? 1 : 0;
        f.farCount += far ? 1 : 0;
    }
    f.boxRatio = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z}) / f.bulkSize;
    return f;
}

} // namespace splatwarp
