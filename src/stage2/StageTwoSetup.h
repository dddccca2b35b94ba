#pragma once
/// @file StageTwoSetup.h
/// @brief Host-side set-up of a Stage II run, identical for the CPU solver (CpuSolver.cpp) and the
///        CUDA one (kernels/StageTwoCuda.cu): input validation, which samples are used, the moving
///        Gaussians, their low-pass filters and the static Gaussians' fixed contribution.
#include <cstdint>
#include <vector>

#include "core/GaussianCloud.h"
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
///        the static Gaussians' contribution once (CPU, oneTBB when options.threaded; left empty
///        without `staticContribution`: the CPU solver evaluates it in its blocks).
StageTwoSetup setupStageTwo(const GaussianCloud& cloud, const SampleSet& samples,
                            const std::vector<std::uint8_t>& moving, const std::vector<std::int32_t>& gaussianCell,
                            const StageTwoOptions& options, bool staticContribution = true);

/// @brief Raw parameters (SH excluded) of Gaussian i of a cloud, in double.
GaussianParams<double> gaussianParamsOf(const GaussianCloud& cloud, std::size_t i);

} // namespace splatwarp
