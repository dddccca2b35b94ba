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

/// The longest axis of Gaussian i (its index) and that axis' world direction.
int longestAxis(const GaussianCloud& g, std::size_t i, Vec3f& direction)
{
    const Vec3f s = g.scale(i);
    int axis = 0;
    for (int a = 1; a < 3; ++a)
        if (s[a] > s[axis]) axis = a;
    const Mat3f r = quatToMatrix(g.rotation(i));
    direction = Vec3f{r.m[0][axis], r.m[1][axis], r.m[2][axis]};
    return axis;
}

} // namespace

void splitGaussian(DensifyCloud& d, std::size_t i, float k, SplitPattern pattern)
{
    GaussianCloud& g = d.cloud;
    Vec3f u;
    const int axis = longestAxis(g, i, u);
    const float offset = k * g.scale(i)[axis];
    if (pattern == SplitPattern::Shrink) {
        g.logScales[3 * i + std::size_t(axis)] += std::log(0.6f);
    } else {
        const float shrink = std::sqrt(1.0f - k * k);
        g.logScales[3 * i + std::size_t(axis)] += std::log(shrink);
        g.opacities[i] = scaledOpacityLogit(g.opacities[i], 1.0 / (2.0 * double(shrink)));
    }
    // The second child: a copy of the first, pushed value by value (a range insert from the vector
    // itself is not allowed).
    const std::size_t j = g.size();
    auto copyTail = [i](std::vector<float>& v, std::size_t width) {
        for (std::size_t c = 0; c < width; ++c) {
            const float value = v[width * i + c];
            v.push_back(value);
        }
    };
    copyTail(g.means, 3);
    copyTail(g.rotations, 4);
    copyTail(g.logScales, 3);
    copyTail(g.opacities, 1);
    copyTail(g.sh, std::size_t(g.shStride()));
    const Vec3f m = g.mean(i);
    g.setMean(i, Vec3f{m.x + offset * u.x, m.y + offset * u.y, m.z + offset * u.z});
    g.setMean(j, Vec3f{m.x - offset * u.x, m.y - offset * u.y, m.z - offset * u.z});
    d.moving.push_back(d.moving[i]);
    d.gaussianCell.push_back(d.gaussianCell[i]);
}

std::size_t splitGaussians(DensifyCloud& d, const std::vector<std::size_t>& which, float offset, SplitPattern pattern)
{
    if (!(offset > 0.0f && offset <= kMaxSplitOffset))
        throw InputError(msg("split: offset ", offset, " is outside (0, ", kMaxSplitOffset, "]"));
    const std::size_t n = d.cloud.size();
    for (std::size_t i : which) {
        if (i >= n) throw InputError(msg("split: Gaussian ", i, " outside 0..", n - 1));
        splitGaussian(d, i, offset, pattern);
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
