#include "stage2/Densify.h"

#include <algorithm>
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

void FitState::replace(std::size_t i, const GaussianCloud& from, const std::vector<std::size_t>& rows,
                       const std::uint8_t* fromMoving, const float* fromCurve)
{
    const bool keepsCurve = curve && !curve->empty();
    for (std::size_t k = 0; k < rows.size(); ++k) {
        std::size_t slot = i;
        if (k == 0) {
            cloud.assign(i, from, rows[k]);
        } else {
            cloud.append(from, rows[k]);
            slot = cloud.size() - 1;
            moving.push_back(moving[i]);
            gaussianCell.push_back(gaussianCell[i]);
            if (parent && !parent->empty()) parent->push_back((*parent)[i]);
            if (keepsCurve) {
                const float row[3] = {(*curve)[3 * i], (*curve)[3 * i + 1], (*curve)[3 * i + 2]};
                curve->insert(curve->end(), row, row + 3);
            }
        }
        if (fromMoving) moving[slot] = fromMoving[rows[k]];
        if (keepsCurve && fromCurve) std::copy_n(fromCurve + 3 * rows[k], 3, curve->begin() + std::ptrdiff_t(3 * slot));
    }
}

void splitGaussian(FitState& d, std::size_t i, const SplitPattern& pattern)
{
    GaussianCloud children;
    children.shDegree = d.cloud.shDegree;
    const std::size_t count = appendSplitChildren(d.cloud, i, longestAxis(d.cloud, i), pattern, children);
    std::vector<std::size_t> rows(count);
    for (std::size_t c = 0; c < count; ++c) rows[c] = c;
    d.replace(i, children, rows);
}

std::size_t splitGaussians(FitState& d, const std::vector<std::size_t>& which, const SplitPattern& pattern)
{
    const std::size_t n = d.cloud.size();
    for (std::size_t i : which) {
        if (i >= n) throw InputError(msg("split: Gaussian ", i, " outside 0..", n - 1));
        splitGaussian(d, i, pattern);
    }
    return which.size();
}

std::size_t pruneMovingBelow(FitState& d, float below)
{
    std::vector<std::uint8_t> drop(d.cloud.size(), 0);
    std::size_t removed = 0;
    for (std::size_t i = 0; i < d.cloud.size(); ++i) {
        drop[i] = d.moving[i] && d.cloud.alpha(i) < below;
        removed += drop[i];
    }
    if (removed == 0) return 0;
    d.cloud.erase(drop);
    eraseRows(d.moving, drop);
    eraseRows(d.gaussianCell, drop);
    if (d.curve && !d.curve->empty()) eraseRows(*d.curve, drop, 3);
    return removed;
}

} // namespace splatwarp
