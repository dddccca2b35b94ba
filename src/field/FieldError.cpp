#include "field/FieldError.h"

#include <cmath>
#include <vector>

#include "core/Error.h"
#include "field/FeatureDevice.h"
#include "sh/SphericalHarmonics.h"

namespace splatwarp {

FieldErrorReport fieldError(const GaussianCloud& rest, const GaussianCloud& deformed, const float* restPoints,
                            const float* warpedPoints, const float* rotations, std::size_t p,
                            const FeatureOptions& options)
{
    if (rest.shDegree != deformed.shDegree)
        throw InputError(msg("field error: rest SH degree ", rest.shDegree, " differs from deformed ", deformed.shDegree));
    const int stride = rest.shStride();
    std::vector<float> fRest(p * std::size_t(stride)), fDef(p * std::size_t(stride)), oRest(p), oDef(p);
    evaluateFeaturesOn(rest, restPoints, p, options, fRest.data(), oRest.data());
    evaluateFeaturesOn(deformed, warpedPoints, p, options, fDef.data(), oDef.data());

    FieldErrorReport r;
    r.points = p;
    double sumO = 0, sumF = 0, dO[2] = {0, 0}, dF[2] = {0, 0};
    std::vector<double> target(static_cast<std::size_t>(stride));
    for (std::size_t j = 0; j < p; ++j) {
        const float* fr = fRest.data() + j * std::size_t(stride);
        for (int s = 0; s < stride; ++s) {
            target[std::size_t(s)] = fr[s];
            sumF += std::fabs(double(fr[s]));
        }
        if (rotations && rest.shDegree > 0) {
            Mat3d rot;
            for (int a = 0; a < 3; ++a)
                for (int b = 0; b < 3; ++b) rot.m[a][b] = rotations[9 * j + std::size_t(3 * a + b)];
            ShRotation(rot, rest.shDegree).apply(rest.shDegree, target.data());
        }
        const int side = oRest[j] > 0.0f ? 0 : 1;
        ++(side == 0 ? r.insidePoints : r.outsidePoints);
        sumO += oRest[j];
        dO[side] += std::fabs(double(oDef[j]) - double(oRest[j]));
        const float* fd = fDef.data() + j * std::size_t(stride);
        for (int s = 0; s < stride; ++s) dF[side] += std::fabs(double(fd[s]) - target[std::size_t(s)]);
    }
    auto ratio = [](double a, double b) { return b > 0 ? a / b : 0.0; };
    r.opacityInside = ratio(dO[0], sumO);
    r.opacityOutside = ratio(dO[1], sumO);
    r.opacity = ratio(dO[0] + dO[1], sumO);
    r.colorInside = ratio(dF[0], sumF);
    r.colorOutside = ratio(dF[1], sumF);
    r.color = ratio(dF[0] + dF[1], sumF);
    return r;
}

} // namespace splatwarp
