#pragma once
/// @file StageTwoCommon.h
/// @brief The parts of Stage II shared by the CPU optimiser (StageTwo.cpp) and the CUDA one
///        (kernels/StageTwoCuda.cu), so both run the same rules: input validation, which
///        samples are used, the static Gaussians' fixed contribution, the filters, the position
///        learning rate and the padded coverage box (host/device).
#include <cstdint>
#include <vector>

#include "core/GaussianCloud.h"
#include "core/HostDevice.h"
#include "core/SmallMath.h"
#include "field/SampleSet.h"
#include "stage2/PairGradients.h"
#include "stage2/StageTwoOptions.h"

namespace splatwarp {

/// @brief Host-side set-up of a Stage II run (identical for every device).
struct StageTwoSetup {
    std::vector<std::uint32_t> used;   ///< [S] indices of the samples used (cell not skipped), ascending
    std::vector<float> x;              ///< [S,3] their warped positions
    std::vector<std::uint32_t> moving; ///< [G] indices of the moving Gaussians, ascending
    std::vector<Mat3d> filter;         ///< [N] low-pass filter of each Gaussian (zero: none)
    std::vector<float> fStatic;        ///< [S,stride] fixed contribution of the static Gaussians to F
    std::vector<float> oStatic;        ///< [S] ... and to O
    float sceneExtent = 0;             ///< largest edge of the used samples' bounding box
};

/// @brief Check array sizes, SH degrees, cell indices and options.
/// @throws InputError naming what is inconsistent
void validateStageTwo(const GaussianCloud& cloud, const SampleSet& samples, const std::vector<std::uint8_t>& moving,
                      const std::vector<std::int32_t>& gaussianCell, const StageTwoOptions& options);

/// @brief Validate, then select the samples, the moving Gaussians and the filters, and evaluate
///        the static Gaussians' contribution once (CPU, oneTBB when options.threaded).
StageTwoSetup setupStageTwo(const GaussianCloud& cloud, const SampleSet& samples,
                            const std::vector<std::uint8_t>& moving, const std::vector<std::int32_t>& gaussianCell,
                            const StageTwoOptions& options);

/// @brief Raw parameters (SH excluded) of Gaussian i of a cloud, in double.
GaussianParams<double> gaussianParamsOf(const GaussianCloud& cloud, std::size_t i);

/// @brief Position learning rate at an iteration: exponential from lrPositionStart to
///        lrPositionEnd over the run, times the scene extent.
float stageTwoPositionRate(const StageTwoOptions& o, int iteration, float sceneExtent);

/// @brief Padded coverage box of one moving Gaussian: its cutoff ellipsoid grown by what
///        `steps` Adam steps can do (each step moves a parameter by about its learning rate:
///        opacity and scale grow the ellipsoid, rotation turns it, the mean moves `move` per
///        axis), plus options.coveragePad relative margin. Empty (hi < lo) when it never counts.
/// @param lo, hi  [3] out
SPLATWARP_HOST_DEVICE void stageTwoCoverageBox(GaussianParams<double> p, const Mat3d& filter, int steps, double move,
                                              const StageTwoOptions& o, float* lo, float* hi)
{
    const double qn = std::sqrt(p.rotation.w * p.rotation.w + p.rotation.x * p.rotation.x +
                                p.rotation.y * p.rotation.y + p.rotation.z * p.rotation.z);
    // Turn bound: 4 raw components each moving ~lrRotation per step, relative to |q|; at most a half turn.
    const double angle = std::min(4.0 * double(steps) * double(o.lrRotation) / std::max(qn, 1e-12), M_PI);
    p.logit += double(steps) * double(o.lrOpacity);
    for (int a = 0; a < 3; ++a) p.logScale[a] += double(steps) * double(o.lrLogScale);
    const Vec3d sc(std::exp(p.logScale.x), std::exp(p.logScale.y), std::exp(p.logScale.z));
    const Mat3d cov = filteredCovariance(p.rotation, sc, filter);
    const double r = extentRadius(sigmoid(p.logit), double(o.cutoff));
    const Vec3d half = ellipsoidHalfExtent(cov, r);
    const double sphere = r * std::sqrt(cov.m[0][0] + cov.m[1][1] + cov.m[2][2]);
    for (int a = 0; a < 3; ++a) {
        const double h =
            r > 0 ? std::min(sphere, half[a] * (1.0 + double(o.coveragePad)) + sphere * angle) + move : -1.0;
        lo[a] = float(p.mean[a] - h);
        hi[a] = float(p.mean[a] + h);
    }
}

} // namespace splatwarp
