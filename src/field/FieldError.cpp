#include "field/FieldError.h"

#include <cmath>
#include <vector>

#include "core/Error.h"
#include "field/FeatureDevice.h"
#include "sh/SphericalHarmonics.h"

namespace splatwarp {

FieldErrorTarget fieldErrorTarget(const GaussianCloud& rest, const float* restPoints, const float* rotations,
                                  std::size_t p, const FeatureOptions& options)
{
    std::vector<float> fRest(p * std::size_t(rest.shStride())), oRest(p);
    evaluateFeaturesOn(rest, restPoints, p, options, fRest.data(), oRest.data());
    return fieldErrorTarget(rest, fRest.data(), std::move(oRest), rotations);
}

FieldErrorTarget fieldErrorTarget(const GaussianCloud& rest, const float* fRest, std::vector<float> oRest,
                                  const float* rotations)
{
    const int stride = rest.shStride();
    const std::size_t p = oRest.size();
    FieldErrorTarget t;
    t.shDegree = rest.shDegree;
    t.opacity = std::move(oRest);
    t.features.resize(p * std::size_t(stride));
    for (std::size_t j = 0; j < p; ++j) {
        const float* fr = fRest + j * std::size_t(stride);
        double* target = t.features.data() + j * std::size_t(stride);
        for (int s = 0; s < stride; ++s) {
            target[s] = fr[s];
            t.sumFeatures += std::fabs(double(fr[s]));
        }
        if (rotations && rest.shDegree > 0) {
            Mat3d rot;
            for (int a = 0; a < 3; ++a)
                for (int b = 0; b < 3; ++b) rot.m[a][b] = rotations[9 * j + std::size_t(3 * a + b)];
            ShRotation(rot, rest.shDegree).apply(rest.shDegree, target);
        }
        t.sumOpacity += t.opacity[j];
    }
    return t;
}

FieldPointErrors fieldPointErrors(const FieldErrorTarget& t, const GaussianCloud& deformed, const float* warpedPoints,
                                  const FeatureOptions& options)
{
    const std::size_t p = t.size();
    std::vector<float> fDef(p * std::size_t(deformed.shStride())), oDef(p);
    evaluateFeaturesOn(deformed, warpedPoints, p, options, fDef.data(), oDef.data());
    return fieldPointErrors(t, deformed, fDef.data(), oDef.data());
}

namespace {

void checkDegrees(const FieldErrorTarget& t, const GaussianCloud& deformed)
{
    if (t.shDegree != deformed.shDegree)
        throw InputError(msg("field error: rest SH degree ", t.shDegree, " differs from deformed ", deformed.shDegree));
}

/// Point j's terms of fieldPointErrors(): weighted |O_def - O_target| and sum of |F_def - F_target|.
inline void pointErrorsAt(const FieldErrorTarget& t, int stride, const float* fDef, const float* oDef, std::size_t j,
                          double& opacity, double& color)
{
    const double* target = t.features.data() + j * std::size_t(stride);
    opacity = std::fabs(double(oDef[j]) - double(t.opacity[j]));
    color = 0.0;
    const float* fd = fDef + j * std::size_t(stride);
    for (int s = 0; s < stride; ++s) color += std::fabs(double(fd[s]) - target[s]);
    if (!t.weight.empty()) {
        opacity *= double(t.weight[j]);
        color *= double(t.weight[j]);
    }
}

} // namespace

FieldPointErrors fieldPointErrors(const FieldErrorTarget& t, const GaussianCloud& deformed, const float* fDef,
                                  const float* oDef)
{
    checkDegrees(t, deformed);
    const std::size_t p = t.size();
    FieldPointErrors e;
    e.opacity.resize(p);
    e.color.resize(p);
    for (std::size_t j = 0; j < p; ++j) pointErrorsAt(t, deformed.shStride(), fDef, oDef, j, e.opacity[j], e.color[j]);
    return e;
}

double fieldPointScoreSum(const FieldErrorTarget& t, const GaussianCloud& deformed, const float* fDef, const float* oDef,
                          double opacityScale, double colorScale)
{
    checkDegrees(t, deformed);
    double sum = 0.0;
    for (std::size_t j = 0; j < t.size(); ++j) {
        double opacity, color;
        pointErrorsAt(t, deformed.shStride(), fDef, oDef, j, opacity, color);
        sum += opacity * opacityScale + color * colorScale;
    }
    return sum;
}

FieldErrorReport fieldError(const FieldErrorTarget& t, const GaussianCloud& deformed, const float* warpedPoints,
                            const FeatureOptions& options)
{
    return fieldErrorOf(t, fieldPointErrors(t, deformed, warpedPoints, options));
}

FieldErrorReport fieldErrorOf(const FieldErrorTarget& t, const FieldPointErrors& e)
{
    FieldErrorReport r;
    r.points = t.size();
    double dO[2] = {0, 0}, dF[2] = {0, 0};
    for (std::size_t j = 0; j < r.points; ++j) {
        const int side = t.opacity[j] > 0.0f ? 0 : 1;
        ++(side == 0 ? r.insidePoints : r.outsidePoints);
        dO[side] += e.opacity[j];
        dF[side] += e.color[j];
    }
    auto ratio = [](double a, double b) { return b > 0 ? a / b : 0.0; };
    r.opacityInside = ratio(dO[0], t.sumOpacity);
    r.opacityOutside = ratio(dO[1], t.sumOpacity);
    r.opacity = ratio(dO[0] + dO[1], t.sumOpacity);
    r.colorInside = ratio(dF[0], t.sumFeatures);
    r.colorOutside = ratio(dF[1], t.sumFeatures);
    r.color = ratio(dF[0] + dF[1], t.sumFeatures);
    return r;
}

FieldErrorReport fieldError(const GaussianCloud& rest, const GaussianCloud& deformed, const float* restPoints,
                            const float* warpedPoints, const float* rotations, std::size_t p,
                            const FeatureOptions& options)
{
    if (rest.shDegree != deformed.shDegree)
        throw InputError(msg("field error: rest SH degree ", rest.shDegree, " differs from deformed ", deformed.shDegree));
    return fieldError(fieldErrorTarget(rest, restPoints, rotations, p, options), deformed, warpedPoints, options);
}

} // namespace splatwarp
