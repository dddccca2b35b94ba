#include "job/WarmStart.h"

#include <algorithm>
#include <cmath>

#include "core/Error.h"

namespace splatwarp {

namespace {

void normalise(float* q)
{
    const float n = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    for (int k = 0; k < 4; ++k) q[k] = n > 0 ? q[k] / n : (k == 0 ? 1.0f : 0.0f);
}

/// a * b (w, x, y, z)
void multiply(const float* a, const float* b, float* out)
{
    out[0] = a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3];
    out[1] = a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2];
    out[2] = a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1];
    out[3] = a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0];
}

std::vector<float> difference(const std::vector<float>& a, const std::vector<float>& b)
{
    std::vector<float> d(a.size());
    for (std::size_t i = 0; i < a.size(); ++i) d[i] = a[i] - b[i];
    return d;
}

} // namespace

StageTwoCorrection stageTwoCorrection(const GaussianCloud& stage1, const GaussianCloud& fitted)
{
    if (stage1.size() != fitted.size() || stage1.shDegree != fitted.shDegree)
        throw InputError("warm start: the fitted model does not match the Stage I model");
    StageTwoCorrection c;
    c.means = difference(fitted.means, stage1.means);
    c.logScales = difference(fitted.logScales, stage1.logScales);
    c.opacities = difference(fitted.opacities, stage1.opacities);
    c.sh = difference(fitted.sh, stage1.sh);
    c.rotations.resize(stage1.rotations.size());
    for (std::size_t i = 0; i < stage1.size(); ++i) {
        float f[4], s[4];
        for (int k = 0; k < 4; ++k) f[k] = fitted.rotations[4 * i + k], s[k] = stage1.rotations[4 * i + k];
        normalise(f);
        normalise(s);
        for (int k = 1; k < 4; ++k) s[k] = -s[k];
        multiply(f, s, &c.rotations[4 * i]);
    }
    return c;
}

void applyCorrection(const StageTwoCorrection& c, const std::vector<std::uint8_t>& moving, GaussianCloud& start)
{
    if (c.opacities.size() != start.size() || c.sh.size() != start.sh.size() || moving.size() != start.size())
        throw InputError("warm start: the correction does not match the model");
    const std::size_t shStride = std::size_t(start.shCoeffs()) * 3;
    for (std::size_t i = 0; i < start.size(); ++i) {
        if (!moving[i]) continue;
        for (int k = 0; k < 3; ++k) {
            start.means[3 * i + k] += c.means[3 * i + k];
            start.logScales[3 * i + k] += c.logScales[3 * i + k];
        }
        start.opacities[i] += c.opacities[i];
        for (std::size_t k = 0; k < shStride; ++k) start.sh[shStride * i + k] += c.sh[shStride * i + k];
        float q[4];
        multiply(&c.rotations[4 * i], &start.rotations[4 * i], q);
        for (int k = 0; k < 4; ++k) start.rotations[4 * i + k] = q[k];
    }
}

std::vector<int> warmShardFrames(const std::vector<int>& frames, const Shard& shard)
{
    std::vector<int> chains; // the chain of each frame, in order
    for (int f : frames)
        if (chains.empty() || chains.back() != f / kWarmChain) chains.push_back(f / kWarmChain);
    const std::size_t n = chains.size(), count = std::size_t(shard.count), index = std::size_t(shard.index);
    const std::size_t begin = n * index / count, end = n * (index + 1) / count;
    std::vector<int> mine;
    for (int f : frames) {
        const auto c = std::size_t(std::lower_bound(chains.begin(), chains.end(), f / kWarmChain) - chains.begin());
        if (c >= begin && c < end) mine.push_back(f);
    }
    return mine;
}

} // namespace splatwarp
