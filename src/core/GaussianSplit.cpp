#include "core/GaussianSplit.h"

#include <cmath>

namespace splatwarp {

int longestAxis(const GaussianCloud& g, std::size_t i)
{
    const Vec3f s = g.scale(i);
    int axis = 0;
    for (int a = 1; a < 3; ++a)
        if (s[a] > s[axis]) axis = a;
    return axis;
}

std::size_t appendSplitChildren(const GaussianCloud& g, std::size_t i, int axis, const SplitPattern& pattern,
                                GaussianCloud& out)
{
    const Mat3f r = quatToMatrix(g.rotation(i));
    const float sigma = g.scale(i)[axis];
    const Vec3f u{r.m[0][axis], r.m[1][axis], r.m[2][axis]};
    const Vec3f m = g.mean(i);
    const float logSigma = float(std::log(pattern.sigma));
    for (std::size_t c = 0; c < pattern.offsets.size(); ++c) {
        out.append(g, i);
        const std::size_t j = out.size() - 1;
        const float d = float(pattern.offsets[c]) * sigma;
        out.setMean(j, Vec3f{m.x + d * u.x, m.y + d * u.y, m.z + d * u.z});
        if (pattern.sigma != 1.0) out.logScales[3 * j + std::size_t(axis)] += logSigma;
        // A weight of 1 keeps the logit bit for bit (the logit of sigmoid(x) need not round to x).
        if (pattern.weights[c] != 1.0) out.opacities[j] = scaledOpacityLogit(g.opacities[i], pattern.weights[c]);
    }
    return pattern.offsets.size();
}

} // namespace splatwarp
