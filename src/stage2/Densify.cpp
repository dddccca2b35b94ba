#include "stage2/Densify.h"

#include <cmath>

#include "core/Error.h"
#include "core/Polar.h"

namespace splatwarp {

std::vector<std::size_t> stretchedGaussians(const std::vector<std::uint8_t>& moving,
                                            const std::vector<std::int32_t>& gaussianCell,
                                            const std::vector<float>& cellGradient, float stretch)
{
    const std::size_t cells = cellGradient.size() / 9;
    std::vector<std::uint8_t> stretched(cells, 0);
    for (std::size_t c = 0; c < cells; ++c) stretched[c] = largestSingularValue(&cellGradient[9 * c]) > stretch;
    std::vector<std::size_t> out;
    for (std::size_t i = 0; i < moving.size(); ++i) {
        const std::int32_t c = gaussianCell[i];
        if (moving[i] && c >= 0 && std::size_t(c) < cells && stretched[std::size_t(c)]) out.push_back(i);
    }
    return out;
}

namespace {

void checkOffset(float k)
{
    if (!(k > 0.0f && k <= kMaxSplitOffset)) throw InputError(msg("split: offset ", k, " is outside (0, ", kMaxSplitOffset, "]"));
}

} // namespace

SplitPattern keepMomentsSplit(float k)
{
    checkOffset(k);
    const float shrink = std::sqrt(1.0f - k * k);
    const double weight = 1.0 / (2.0 * double(shrink));
    return {double(shrink), {double(k), -double(k)}, {weight, weight}};
}

SplitPattern shrinkSplit(float k)
{
    checkOffset(k);
    return {double(0.6f), {double(k), -double(k)}, {1.0, 1.0}};
}

void splitGaussian(DensifyCloud& d, std::size_t i, const SplitPattern& pattern)
{
    GaussianCloud children;
    children.shDegree = d.cloud.shDegree;
    const std::size_t count = appendSplitChildren(d.cloud, i, longestAxis(d.cloud, i), pattern, children);
    d.cloud.assign(i, children, 0);
    for (std::size_t c = 1; c < count; ++c) {
        d.cloud.append(children, c);
        d.moving.push_back(d.moving[i]);
        d.gaussianCell.push_back(d.gaussianCell[i]);
    }
}

std::size_t splitGaussians(DensifyCloud& d, const std::vector<std::size_t>& which, const SplitPattern& pattern)
{
    const std::size_t n = d.cloud.size();
    for (std::size_t i : which) {
        if (i >= n) throw InputError(msg("split: Gaussian ", i, " outside 0..", n - 1));
        splitGaussian(d, i, pattern);
    }
    return which.size();
}

std::size_t pruneMovingBelow(DensifyCloud& d, float below)
{
    GaussianCloud kept;
    kept.shDegree = d.cloud.shDegree;
    std::vector<std::uint8_t> moving;
    std::vector<std::int32_t> cell;
    for (std::size_t i = 0; i < d.cloud.size(); ++i) {
        if (d.moving[i] && d.cloud.alpha(i) < below) continue;
        kept.append(d.cloud, i);
        moving.push_back(d.moving[i]);
        cell.push_back(d.gaussianCell[i]);
    }
    const std::size_t removed = d.cloud.size() - kept.size();
    d.cloud = std::move(kept);
    d.moving = std::move(moving);
    d.gaussianCell = std::move(cell);
    return removed;
}

} // namespace splatwarp
