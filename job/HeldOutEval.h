#pragma once
/// @file HeldOutEval.h
/// @brief Field fidelity of a deformed model at held-out points X (continuous positions, not the
///        training samples) pushed through the deformation x = phi(X); see fieldError() in
///        src/field/FieldError.h. Two point sets: the fixed judge's (drawJudgePoints(): the rest
///        model alone decides them, no low-pass filter; what `eval` and the reports use) and the
///        training lattice's (drawHeldOutPoints(): a SampleGrid's active cells and rest filter).
#include <cstdint>
#include <vector>

#include <nlohmann/json.hpp>

#include "vdb/SampleGrid.h"
#include "core/Device.h"
#include "deform/Deformation.h"
#include "field/FieldError.h"

namespace splatwarp {

/// @brief Options of the held-out evaluation.
struct HeldOutOptions {
    std::size_t points = 100000; ///< held-out points (uniform over the active rest cells)
    std::uint32_t seed = 1;      ///< deterministic for a seed
    /// Where the points are warped and the features at them evaluated (HeldOutPoints::features.device).
    ResolvedDevice device;
};

/// @brief Held-out points with their warped positions and local rotations.
struct HeldOutPoints {
    std::vector<float> rest;      ///< [P,3] X
    std::vector<float> warped;    ///< [P,3] x = phi(X)
    std::vector<float> rotations; ///< [P,9] polar rotation of the local deformation gradient
    FeatureOptions features;      ///< cutoff and (rest, isotropic) filter of the grid's targets; the device of every step
    std::size_t size() const { return rest.size() / 3; }
};

/// Cells of the judge's region lattice along the rest model's largest extent: a constant of the
/// judge, so the region never depends on training flags. It only bounds where points fall.
constexpr int kJudgeRegionCells = 128;

/// @brief The judge's region: the cells of an h = extent / kJudgeRegionCells lattice that any
///        Gaussian's unfiltered cutoff box (alpha*G >= 1/255) overlaps, plus one cell around them
///        (the outside band). Cell (i,j,k) spans [i h, (i+1) h) x ... with i = origin[0] + cells[3c].
struct JudgeRegion {
    double cellSize = 0.0;
    std::int64_t origin[3] = {0, 0, 0};
    std::vector<std::int32_t> cells; ///< [C,3] coordinates relative to origin, in x-major order
    std::size_t size() const { return cells.size() / 3; }
};

/// @throws InputError when no Gaussian reaches the cutoff or the model has zero extent
JudgeRegion judgeRegion(const GaussianCloud& rest, bool threaded = true);

/// @brief The feature options of the judge: cutoff 1/255 and no low-pass filter (each model's
///        own Gaussians only, as a renderer sees them).
FeatureOptions judgeFeatureOptions();

/// @brief The fixed judge's held-out points: uniform over judgeRegion(rest), features with
///        judgeFeatureOptions(); depends on the rest model, points and seed only.
HeldOutPoints drawJudgePoints(const GaussianCloud& rest, const HeldOutOptions& options = {});
/// @brief The same points from judgeRegion(rest) made once (many draws of one model).
HeldOutPoints drawJudgePoints(const JudgeRegion& region, const HeldOutOptions& options);

/// @brief Draw held-out points in the grid's active cells and warp them with the deformation
///        (the training-lattice error: the grid's cells, cutoff and rest filter).
HeldOutPoints makeHeldOutPoints(const SampleGrid& grid, const Deformation& deformation, const HeldOutOptions& options = {});

/// @brief The rest side of makeHeldOutPoints(): the points X only (warped = X, rotations identity).
HeldOutPoints drawHeldOutPoints(const SampleGrid& grid, const HeldOutOptions& options = {});

/// @brief The per-deformation side of makeHeldOutPoints(): x = phi(X) and R_p on points.features.device.
void warpHeldOutPoints(HeldOutPoints& points, const Deformation& deformation, bool threaded = true);

/// @brief Field error of `deformed` against `rest` pushed through the deformation, at the points;
///        the feature evaluations run on points.features.device (Auto: CPU fallback on
///        out-of-GPU-memory).
FieldErrorReport evaluateHeldOut(const GaussianCloud& rest, const GaussianCloud& deformed, const HeldOutPoints& points);

/// @brief The rest side of evaluateHeldOut() (rest features at the points, SH rotated), for
///        judging several deformed models against one rest model without recomputing it.
FieldErrorTarget heldOutTarget(const GaussianCloud& rest, const HeldOutPoints& points);

/// @brief The rest features at the points without the SH rotation (computed once per rest model).
FieldErrorTarget unrotatedTarget(const GaussianCloud& rest, const HeldOutPoints& points);

/// @brief unrotatedTarget() rotated by the points' R_p: equal to heldOutTarget(rest, points).
FieldErrorTarget rotatedTarget(const FieldErrorTarget& unrotated, const HeldOutPoints& points);

/// @brief evaluateHeldOut() against a precomputed rest side (heldOutTarget() of the same points).
FieldErrorReport evaluateHeldOut(const FieldErrorTarget& target, const GaussianCloud& deformed,
                                 const HeldOutPoints& points);

/// @brief The per-point terms of evaluateHeldOut() (the validation score's, job/Judge.h). The
///        deformed model is evaluated at the warped points by the block engine on the CPU
///        (stage2/BlockFeatures.h evaluatePointsOn(): the same bits as point by point).
FieldPointErrors heldOutPointErrors(const FieldErrorTarget& target, const GaussianCloud& deformed,
                                    const HeldOutPoints& points);

/// @brief JSON of a report: opacity, color, points, inside{...}, outside{...}.
nlohmann::json fieldErrorJson(const FieldErrorReport& report);

} // namespace splatwarp
