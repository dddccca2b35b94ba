#include "core/GaussianCloud.h"

#include <algorithm>
#include <cstring>
#include <cmath>

#include "core/Error.h"

namespace splatwarp {

void GaussianCloud::resize(std::size_t n, int degree)
{
    if (degree < 0 || degree > 3) throw InputError(msg("SH degree ", degree, " is outside 0..3"));
    shDegree = degree;
    means.assign(3 * n, 0.0f);
    rotations.assign(4 * n, 0.0f);
    for (std::size_t i = 0; i < n; ++i) rotations[4 * i] = 1.0f;
    logScales.assign(3 * n, 0.0f);
    opacities.assign(n, 0.0f);
    sh.assign(n * std::size_t(shStride()), 0.0f);
}

void GaussianCloud::erase(const std::vector<std::uint8_t>& drop)
{
    if (drop.size() != size()) throw InputError(msg("erase: ", drop.size(), " flags for ", size(), " Gaussians"));
    eraseRows(means, drop, 3);
    eraseRows(rotations, drop, 4);
    eraseRows(logScales, drop, 3);
    eraseRows(opacities, drop);
    eraseRows(sh, drop, std::size_t(shStride()));
}

void GaussianCloud::append(const GaussianCloud& o, std::size_t i)
{
    means.insert(means.end(), o.means.begin() + 3 * i, o.means.begin() + 3 * i + 3);
    rotations.insert(rotations.end(), o.rotations.begin() + 4 * i, o.rotations.begin() + 4 * i + 4);
    logScales.insert(logScales.end(), o.logScales.begin() + 3 * i, o.logScales.begin() + 3 * i + 3);
    opacities.push_back(o.opacities[i]);
    sh.insert(sh.end(), o.shOf(i), o.shOf(i) + o.shStride());
}

void GaussianCloud::assign(std::size_t i, const GaussianCloud& o, std::size_t j)
{
    std::copy_n(o.means.begin() + std::ptrdiff_t(3 * j), 3, means.begin() + std::ptrdiff_t(3 * i));
    std::copy_n(o.rotations.begin() + std::ptrdiff_t(4 * j), 4, rotations.begin() + std::ptrdiff_t(4 * i));
    std::copy_n(o.logScales.begin() + std::ptrdiff_t(3 * j), 3, logScales.begin() + std::ptrdiff_t(3 * i));
    opacities[i] = o.opacities[j];
    std::copy_n(o.shOf(j), o.shStride(), shOf(i));
}

bool GaussianCloud::sameGaussian(std::size_t i, const GaussianCloud& o, std::size_t j) const
{
    auto same = [](const float* a, const float* b, std::size_t n) { return std::memcmp(a, b, n * sizeof(float)) == 0; };
    return shDegree == o.shDegree && same(&means[3 * i], &o.means[3 * j], 3) &&
           same(&rotations[4 * i], &o.rotations[4 * j], 4) && same(&logScales[3 * i], &o.logScales[3 * j], 3) &&
           same(&opacities[i], &o.opacities[j], 1) && same(shOf(i), o.shOf(j), std::size_t(shStride()));
}

float scaledOpacityLogit(float logit, double w)
{
    const double a = w / (1.0 + std::exp(-double(logit)));
    return a > 0 ? float(std::log(a) - std::log1p(-a)) : float(double(logit) + std::log(w));
}

void GaussianCloud::checkConsistent() const
{
    if (shDegree < 0 || shDegree > 3) throw InputError(msg("SH degree ", shDegree, " is outside 0..3"));
    const std::size_t n = size();
    if (means.size() != 3 * n || rotations.size() != 4 * n || logScales.size() != 3 * n ||
        sh.size() != n * std::size_t(shStride()))
        throw InputError("GaussianCloud arrays have inconsistent sizes");
}

Vec3f GaussianCloud::scale(std::size_t i) const
{
    return {std::exp(logScales[3 * i]), std::exp(logScales[3 * i + 1]), std::exp(logScales[3 * i + 2])};
}

void centreBounds(const GaussianCloud& g, Vec3f& lo, Vec3f& hi)
{
    lo = hi = Vec3f(0, 0, 0);
    if (g.empty()) return;
    lo = hi = g.mean(0);
    for (std::size_t i = 1; i < g.size(); ++i) {
        const Vec3f p = g.mean(i);
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], p[a]);
            hi[a] = std::max(hi[a], p[a]);
        }
    }
}

GaussianCloud withShDegree(const GaussianCloud& g, int degree)
{
    GaussianCloud out;
    out.resize(g.size(), degree); // throws for a degree outside 0..3
    out.means = g.means;
    out.rotations = g.rotations;
    out.logScales = g.logScales;
    out.opacities = g.opacities;
    const int keep = std::min(g.shStride(), out.shStride());
    for (std::size_t i = 0; i < g.size(); ++i) std::copy(g.shOf(i), g.shOf(i) + keep, out.shOf(i));
    return out;
}

} // namespace splatwarp
