#pragma once
/// @file Coverage.h
/// @brief Stage II coverage: where a moving Gaussian can reach within the next rebuild interval
///        (a padded box plus three slabs along its own axes, which cut the box down for thin or
///        turned Gaussians), and whether a coverage still holds every pair it can count.
///        Host/device: used by the CPU block coverage (SampleBlocks.h, CpuSolver.cpp) and the CUDA
///        per-sample coverage (kernels/StageTwoCuda.cu).
#include <algorithm>
#include <cmath>

#include "core/HostDevice.h"
#include "core/SmallMath.h"
#include "stage2/PairGradients.h"
#include "stage2/StageTwoOptions.h"

namespace splatwarp {

/// @brief Three slabs |axis[a] . (p - centre)| <= half[a] (a box in a rotated frame).
struct CoverageSlabs {
    float centre[3] = {0, 0, 0};
    float axis[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    float half[3] = {-1, -1, -1};

    /// @brief Whether p lies in all three slabs (float arithmetic, as in Coverage::build).
    SPLATWARP_HOST_DEVICE bool contains(const float* p) const
    {
        const float d[3] = {p[0] - centre[0], p[1] - centre[1], p[2] - centre[2]};
        for (int a = 0; a < 3; ++a)
            if (!(std::fabs(axis[a][0] * d[0] + axis[a][1] * d[1] + axis[a][2] * d[2]) <= half[a])) return false;
        return true;
    }
};

/// @brief What a moving Gaussian can reach within `steps` Adam steps, assuming each step changes
///        a parameter by about its learning rate: opacity and scale grow the cutoff ellipsoid
///        (cov, radius), rotation turns it by up to `angle` (so its points move by at most
///        sphere * angle), the mean moves `move` per axis.
struct StageTwoReach {
    Vec3d mean;
    Mat3d cov;          ///< filtered covariance with every log-scale grown by steps * lrLogScale
    double radius = 0;  ///< Mahalanobis cutoff radius at the grown opacity (0: never counts)
    double sphere = 0;  ///< radius * sqrt(trace cov): a ball holding the ellipsoid in any orientation
    double angle = 0;   ///< turn bound in radians
    double move = 0;    ///< per-axis mean motion
};

/// @brief How many steps a coverage built at `iteration` is sized for (never past the last step).
SPLATWARP_HOST_DEVICE int coverageReachSteps(const StageTwoOptions& o, int iteration)
{
    const int left = o.iterations - iteration;
    return left < o.coverageSteps ? (left > 1 ? left : 1) : o.coverageSteps;
}

/// @brief The reach of one moving Gaussian (see StageTwoReach).
SPLATWARP_HOST_DEVICE StageTwoReach stageTwoReach(GaussianParams<double> p, const Mat3d& filter, int steps, double move,
                                                  const StageTwoOptions& o)
{
    const double qn = std::sqrt(p.rotation.w * p.rotation.w + p.rotation.x * p.rotation.x +
                                p.rotation.y * p.rotation.y + p.rotation.z * p.rotation.z);
    StageTwoReach r;
    r.mean = p.mean;
    r.move = move;
    // Turn bound: 4 raw components each moving ~lrRotation per step, relative to |q|; at most a half turn.
    r.angle = std::min(4.0 * double(steps) * double(o.lrRotation) / std::max(qn, 1e-12), M_PI);
    p.logit += double(steps) * double(o.lrOpacity);
    for (int a = 0; a < 3; ++a) p.logScale[a] += double(steps) * double(o.lrLogScale);
    const Vec3d sc(std::exp(p.logScale.x), std::exp(p.logScale.y), std::exp(p.logScale.z));
    r.cov = filteredCovariance(p.rotation, sc, filter);
    r.radius = extentRadius(sigmoid(p.logit), double(o.cutoff));
    r.sphere = r.radius * std::sqrt(r.cov.m[0][0] + r.cov.m[1][1] + r.cov.m[2][2]);
    return r;
}

/// @brief Half width of the reach along a unit direction n: the grown ellipsoid's support
///        (plus options.coveragePad relative margin), plus the turn and the motion, capped by
///        the ball that holds the ellipsoid in any orientation. Negative when it never counts.
SPLATWARP_HOST_DEVICE double stageTwoReachWidth(const StageTwoReach& r, const Vec3d& n, double support,
                                                const StageTwoOptions& o)
{
    const double motion = r.move * (std::fabs(n.x) + std::fabs(n.y) + std::fabs(n.z));
    return r.radius > 0 ? std::min(r.sphere, support * (1.0 + double(o.coveragePad)) + r.sphere * r.angle) + motion : -1.0;
}

/// @brief Padded coverage box of one moving Gaussian: the AABB of its reach (StageTwoReach)
///        plus options.coveragePad relative margin. Empty (hi < lo) when it never counts.
/// @param lo, hi  [3] out
SPLATWARP_HOST_DEVICE void stageTwoCoverageBox(const GaussianParams<double>& p, const Mat3d& filter, int steps, double move,
                                              const StageTwoOptions& o, float* lo, float* hi)
{
    const StageTwoReach r = stageTwoReach(p, filter, steps, move, o);
    const Vec3d half = ellipsoidHalfExtent(r.cov, r.radius);
    for (int a = 0; a < 3; ++a) {
        Vec3d n(0, 0, 0);
        n[a] = 1;
        const double h = stageTwoReachWidth(r, n, half[a], o);
        lo[a] = float(p.mean[a] - h);
        hi[a] = float(p.mean[a] + h);
    }
}

/// Relative allowance for the float rounding of the coverage tests (|n . (x - c)| and the box
/// comparisons on coordinates of this size): a few hundred float ulps.
constexpr double kCoverageRounding = 1e-5;

/// @brief The Mahalanobis radius a prepared Gaussian's pruning tests allow (prepareGaussian pads it).
SPLATWARP_HOST_DEVICE double prunedRadius(double r)
{
    const double a = r * (1 + kPrunePad), b = std::sqrt(r * r * (1 + kPrunePad) + kPrunePad);
    return a > b ? a : b;
}

/// @brief Support of the ellipsoid x^T cov^-1 x <= radius^2 along a unit direction n.
SPLATWARP_HOST_DEVICE double ellipsoidSupport(const Mat3d& cov, const Vec3d& n, double radius)
{
    double q = 0;
    for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) q += n[a] * cov.m[a][b] * n[b];
    return radius * std::sqrt(q > 0 ? q : 0.0);
}

/// @brief Coverage slabs of one moving Gaussian along its own axes, holding the same reach as
///        the box (the ellipsoid's support along each axis, plus the turn and the motion); for a
///        flat or turned Gaussian they hold far fewer samples than its box.
SPLATWARP_HOST_DEVICE void stageTwoCoverageSlabs(const GaussianParams<double>& p, const Mat3d& filter, int steps,
                                                 double move, const StageTwoOptions& o, CoverageSlabs& out)
{
    const StageTwoReach r = stageTwoReach(p, filter, steps, move, o);
    const Mat3d rot = quatToMatrix(p.rotation);
    for (int a = 0; a < 3; ++a) {
        out.centre[a] = float(p.mean[a]);
        const Vec3d n(rot.m[0][a], rot.m[1][a], rot.m[2][a]);
        for (int b = 0; b < 3; ++b) out.axis[a][b] = float(n[b]);
        // The pruning pad and the rounding allowance keep the Gaussian as it is now inside
        // (stageTwoCoverageHolds) even with no learning rate at all.
        const double h = stageTwoReachWidth(r, n, ellipsoidSupport(r.cov, n, prunedRadius(r.radius)), o);
        out.half[a] = float(h < 0 ? h : h * (1 + kCoverageRounding) + kCoverageRounding * r.sphere);
    }
}

/// @brief Whether every pair Gaussian p can count now (its prepared, padded cutoff ellipsoid)
///        is still inside its coverage box [lo, hi] and slabs, with margin for the float
///        rounding of those tests: when it is, the coverage still holds all its counted pairs.
SPLATWARP_HOST_DEVICE bool stageTwoCoverageHolds(const GaussianParams<double>& p, const Mat3d& filter, double cutoff,
                                                 const float* lo, const float* hi, const CoverageSlabs& slabs)
{
    const Vec3d sc(std::exp(p.logScale.x), std::exp(p.logScale.y), std::exp(p.logScale.z));
    const Mat3d cov = filteredCovariance(p.rotation, sc, filter);
    const double r = extentRadius(sigmoid(p.logit), cutoff);
    if (!(r > 0)) return true; // never counts (prepareGaussian leaves it empty)
    // Box: weight() tests the float AABB mean +- halfExtent first, so a counted pair lies in it.
    const Vec3d half = ellipsoidHalfExtent(cov, r * (1 + kPrunePad));
    for (int a = 0; a < 3; ++a) {
        const double h = half[a] * (1 + kCoverageRounding);
        if (!(p.mean[a] - h >= double(lo[a]) && p.mean[a] + h <= double(hi[a]))) return false;
    }
    // Slabs: a counted pair lies in the padded ellipsoid, whose support along n is below.
    const double rp = prunedRadius(r);
    const double sphere = rp * std::sqrt(cov.m[0][0] + cov.m[1][1] + cov.m[2][2]);
    for (int a = 0; a < 3; ++a) {
        const Vec3d n(slabs.axis[a][0], slabs.axis[a][1], slabs.axis[a][2]);
        double off = 0, reach = 0;
        for (int b = 0; b < 3; ++b) {
            off += n[b] * (p.mean[b] - double(slabs.centre[b]));
            reach += std::fabs(p.mean[b] - double(slabs.centre[b]));
        }
        const double need = std::fabs(off) + ellipsoidSupport(cov, n, rp) + kCoverageRounding * (sphere + reach);
        if (!(need <= double(slabs.half[a]))) return false;
    }
    return true;
}

} // namespace splatwarp
