#pragma once
/// @file StageTwoSolver.h
/// @brief What a Stage II device implementation provides (the CPU solver in CpuSolver.h, the
///        CUDA one in kernels/StageTwoCuda.cu) to the one optimisation loop (StageTwoLoop.h),
///        which owns the schedule, the rebuild policy, best-iterate keeping and the report.
///        Every solver holds the moving Gaussians in the packed layout of StageTwoParams.h.
#include <cstdint>

#include "core/GaussianCloud.h"
#include "stage2/StageTwo.h"
#include "stage2/StageTwoParams.h"

namespace splatwarp {

/// @brief Time per phase of a solver, milliseconds.
struct StageTwoPhaseTimes {
    double coverage = 0, forward = 0, backward = 0, update = 0;
};

class StageTwoSolver {
public:
    virtual ~StageTwoSolver() = default;
    /// @brief The device that runs it.
    virtual Device device() const = 0;
    /// @brief Counts known after set-up (samples used and skipped, moving Gaussians, scene extent).
    virtual void describe(StageTwoReport& report) const = 0;
    /// @brief Prepare the Gaussians (PreparedGaussian) from the current parameters.
    virtual void prepare() = 0;
    /// @brief Build the coverage for the next coverageReachSteps() steps. onlyEscaped: called
    ///        because coverageHolds() was false; a solver may then rebuild only the Gaussians that
    ///        left theirs (the others' still holds every pair they can count).
    virtual void rebuildCoverage(int iteration, bool onlyEscaped) = 0;
    /// @brief Whether every moving Gaussian still lies inside the reach its coverage was built for
    ///        (stageTwoCoverageHolds), so no counted pair can be missing.
    virtual bool coverageHolds() = 0;
    /// @brief Candidate pairs of the last coverage.
    virtual std::uint64_t coveragePairs() const = 0;
    /// @brief Forward pass: features, loss and its gradient; the energy and the counted pairs.
    virtual StageTwoEnergy forward(int iteration, std::uint64_t& pairs) = 0;
    /// @brief Backward pass into the packed parameter gradients.
    virtual void backward() = 0;
    /// @brief One Adam step from the current parameters with the gradient of the last backward();
    ///        returns its first-order energy decrease (gradient . step, summed in row order).
    virtual double step(const StageTwoStep& s) = 0;
    /// @brief Keep a copy of the current parameters and Adam moments / put that copy back (the
    ///        gradient is left alone, so a step can be taken again from the kept iterate).
    virtual void saveIterate() = 0;
    virtual void restoreIterate() = 0;
    /// @brief Write the current parameters into the moving Gaussians of a cloud.
    virtual void writeTo(GaussianCloud& cloud) const = 0;
    /// @brief Time spent per phase so far.
    virtual StageTwoPhaseTimes times() const = 0;
    /// @brief CUDA: peak device memory of the run's buffers; CPU: 0.
    virtual std::uint64_t peakDeviceBytes() const { return 0; }
};

} // namespace splatwarp
