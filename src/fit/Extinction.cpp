#include "fit/Extinction.h"

#include <algorithm>
#include <cmath>

#include "render/SplatProjection.h"

namespace splatwarp {

namespace {
const double kSqrt2Pi = std::sqrt(2.0 * M_PI);

double geometricMeanScale(const GaussianCloud& cloud, std::size_t i)
{
    const float* l = &cloud.logScales[3 * i];
    return std::exp((double(l[0]) + l[1] + l[2]) / 3.0);
}

float logit(double a)
{
    a = std::clamp(a, 1e-7, 1.0 - 1e-7);
    return float(std::log(a / (1.0 - a)));
}
} // namespace

double centreOpticalDepth(const GaussianCloud& cloud, std::size_t i, double densityScale)
{
    return double(cloud.alpha(i)) * densityScale * kSqrt2Pi * geometricMeanScale(cloud, i);
}

std::size_t extinctionToOpacity(GaussianCloud& cloud, double densityScale)
{
    std::size_t capped = 0;
    for (std::size_t i = 0; i < cloud.size(); ++i) {
        double alpha = 1.0 - std::exp(-centreOpticalDepth(cloud, i, densityScale));
        if (alpha > kSplatMaxAlpha) {
            alpha = kSplatMaxAlpha;
            ++capped;
        }
        cloud.opacities[i] = logit(alpha);
    }
    return capped;
}

void opacityToExtinction(GaussianCloud& cloud, double densityScale)
{
    for (std::size_t i = 0; i < cloud.size(); ++i) {
        const double tau = -std::log(1.0 - double(cloud.alpha(i)));
        cloud.opacities[i] = logit(tau / (kSqrt2Pi * geometricMeanScale(cloud, i) * densityScale));
    }
}

} // namespace splatwarp
