#include "fit/Extinction.h"

#include <algorithm>
#include <cmath>

#include "render/SplatProjection.h"

namespace splatwarp {

namespace {
const double kSqrt2Pi = std::sqrt(2.0 * M_PI);
/// Duplication steps of the Carlson integrals: finite arguments converge in under 30 (each step
/// roughly halves the spread's exponent, then quarters it); a NaN never does and spun forever.
constexpr int kMaxDuplications = 100;

/// Carlson's R_F(x, y, z) by duplication (x, y, z >= 0, at most one zero; relative error ~1e-16).
double carlsonRF(double x, double y, double z)
{
    double a = 0, dx = 0, dy = 0, dz = 0;
    for (int step = 0; step < kMaxDuplications; ++step) {
        const double sx = std::sqrt(x), sy = std::sqrt(y), sz = std::sqrt(z);
        const double l = sx * (sy + sz) + sy * sz;
        x = 0.25 * (x + l), y = 0.25 * (y + l), z = 0.25 * (z + l);
        a = (x + y + z) / 3.0;
        dx = (a - x) / a, dy = (a - y) / a, dz = (a - z) / a;
        if (std::max({std::fabs(dx), std::fabs(dy), std::fabs(dz)}) < 0.0025) break;
    }
    const double e2 = dx * dy - dz * dz, e3 = dx * dy * dz;
    return (1.0 + (e2 / 24.0 - 0.1 - 3.0 * e3 / 44.0) * e2 + e3 / 14.0) / std::sqrt(a);
}

/// Carlson's R_D(x, y, z) = R_J(x, y, z, z) by duplication (z > 0).
double carlsonRD(double x, double y, double z)
{
    const double c1 = 3.0 / 14.0, c2 = 1.0 / 6.0, c3 = 9.0 / 22.0, c4 = 3.0 / 26.0;
    double sum = 0, fac = 1, a = 0, dx = 0, dy = 0, dz = 0;
    for (int step = 0; step < kMaxDuplications; ++step) {
        const double sx = std::sqrt(x), sy = std::sqrt(y), sz = std::sqrt(z);
        const double l = sx * (sy + sz) + sy * sz;
        sum += fac / (sz * (z + l));
        fac *= 0.25;
        x = 0.25 * (x + l), y = 0.25 * (y + l), z = 0.25 * (z + l);
        a = 0.2 * (x + y + 3.0 * z);
        dx = (a - x) / a, dy = (a - y) / a, dz = (a - z) / a;
        if (std::max({std::fabs(dx), std::fabs(dy), std::fabs(dz)}) < 0.0015) break;
    }
    const double ea = dx * dy, eb = dz * dz, ec = ea - eb, ed = ea - 6.0 * eb, ee = ed + ec + ec;
    return 3.0 * sum + fac *
                           (1.0 + ed * (-c1 + 0.25 * c3 * ed - 1.5 * c4 * dz * ee) +
                            dz * (c2 * ee + dz * (-c3 * ec + dz * c4 * ea))) /
                           (a * std::sqrt(a));
}

/// Direction mean of sqrt(d^T Sigma^-1 d) for the Gaussian with these log-scales.
double meanInverseDepth(const float* logScales)
{
    double l[3] = {logScales[0], logScales[1], logScales[2]};
    std::sort(l, l + 3);
    // Homogeneous of degree 1/2: scale by the middle axis, so no value over- or underflows.
    return std::exp(-l[1]) * meanRootQuadratic(std::exp(2.0 * (l[1] - l[0])), std::exp(2.0 * (l[1] - l[2])), 1.0);
}

float logit(double a)
{
    a = std::clamp(a, 1e-7, 1.0 - 1e-7);
    return float(std::log(a / (1.0 - a)));
}
} // namespace

double meanRootQuadratic(double a, double b, double c)
{
    double v[3] = {a, b, c};
    std::sort(v, v + 3);
    const double x = v[0], y = v[2], z = v[1]; // z in the middle: (x - z)(y - z) <= 0, no cancellation
    return 0.5 * (z * carlsonRF(x, y, z) - (x - z) * (y - z) * carlsonRD(x, y, z) / 3.0 + std::sqrt(x * y / z));
}

double splatOpticalDepth(const GaussianCloud& cloud, std::size_t i, double densityScale)
{
    return double(cloud.alpha(i)) * densityScale * kSqrt2Pi / meanInverseDepth(&cloud.logScales[3 * i]);
}

std::size_t extinctionToOpacity(GaussianCloud& cloud, double densityScale)
{
    std::size_t capped = 0;
    for (std::size_t i = 0; i < cloud.size(); ++i) {
        double alpha = 1.0 - std::exp(-splatOpticalDepth(cloud, i, densityScale));
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
        cloud.opacities[i] = logit(tau * meanInverseDepth(&cloud.logScales[3 * i]) / (kSqrt2Pi * densityScale));
    }
}

} // namespace splatwarp
