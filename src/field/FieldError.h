#pragma once
/// @file FieldError.h
/// @brief Field fidelity of a deformed model at held-out points (`splatwarp eval`):
///        compares the deformed model's features at warped points x = phi(X) with the rest
///        model's features at the rest points X (SH rotated by the local rotation R_p).
#include <cstddef>
#include <vector>

#include "core/GaussianCloud.h"
#include "field/FeatureField.h"

namespace splatwarp {

/// @brief Relative L1 errors. Every ratio is normalised by the TOTAL rest sum (sum O_rest(X) for
///        opacity, sum |F_rest(X)|_1 for colour), so inside + outside = total.
struct FieldErrorReport {
    double opacity = 0.0;        ///< sum |O_def(x) - O_rest(X)| / sum O_rest(X)
    double color = 0.0;          ///< sum |F_def(x) - R_p F_rest(X)|_1 / sum |F_rest(X)|_1
    double opacityInside = 0.0;  ///< the opacity sum restricted to points with O_rest(X) > 0
    double colorInside = 0.0;
    double opacityOutside = 0.0; ///< restricted to O_rest(X) = 0: leakage into empty space
    double colorOutside = 0.0;
    std::size_t points = 0, insidePoints = 0, outsidePoints = 0;
};

/// @brief The rest side of the comparison: fixed for a rest model and a point set, so a run that
///        judges several deformed models (Stage I, the Stage II curve, the result) computes it once.
struct FieldErrorTarget {
    int shDegree = 0;
    std::vector<float> opacity;   ///< [P] O_rest(X)
    std::vector<double> features; ///< [P,stride] R_p F_rest(X)
    double sumOpacity = 0.0;      ///< sum O_rest(X)
    double sumFeatures = 0.0;     ///< sum |F_rest(X)|_1
    /// [P] each point's weight in every sum (a thinned point set: one over its keep probability);
    /// empty: every point 1.
    std::vector<float> weight;
    std::size_t size() const { return opacity.size(); }
    double weightOf(std::size_t j) const { return weight.empty() ? 1.0 : double(weight[j]); }
};

/// @brief The rest features at X, SH rotated by R_p (arguments as fieldError()).
FieldErrorTarget fieldErrorTarget(const GaussianCloud& rest, const float* restPoints, const float* rotations,
                                  std::size_t p, const FeatureOptions& options = {});

/// @brief The same from the rest model's features at X, already evaluated: fRest [P,stride] and
///        oRest [P] (any evaluator with the same bits, e.g. the Stage II block engine).
FieldErrorTarget fieldErrorTarget(const GaussianCloud& rest, const float* fRest, std::vector<float> oRest,
                                  const float* rotations);

/// @brief Held-out field error of a deformed model against a precomputed rest side.
/// @param warpedPoints [P,3] x = phi(X), P = target.size()
FieldErrorReport fieldError(const FieldErrorTarget& target, const GaussianCloud& deformed, const float* warpedPoints,
                            const FeatureOptions& options = {});

/// @brief Per point j: |O_def - O_target| and sum over the SH stride of |F_def - F_target|, times
///        the point's weight: the terms fieldError() sums (over the target's sumOpacity and sumFeatures).
struct FieldPointErrors {
    std::vector<double> opacity, color;
};

/// @brief The per-point terms of fieldError() (same arguments).
FieldPointErrors fieldPointErrors(const FieldErrorTarget& target, const GaussianCloud& deformed,
                                  const float* warpedPoints, const FeatureOptions& options = {});

/// @brief The per-point terms from the deformed model's features at the points, evaluated by the
///        caller: fDef [P, deformed.shStride()], oDef [P]. @throws InputError when the SH degrees differ
FieldPointErrors fieldPointErrors(const FieldErrorTarget& target, const GaussianCloud& deformed, const float* fDef,
                                  const float* oDef);

/// @brief The sum over points of fieldPointErrors()' opacity * opacityScale + color * colorScale,
///        in point order, without the per-point arrays (the same bits as summing them).
double fieldPointScoreSum(const FieldErrorTarget& target, const GaussianCloud& deformed, const float* fDef,
                          const float* oDef, double opacityScale, double colorScale);

/// @brief fieldError() from its per-point terms.
FieldErrorReport fieldErrorOf(const FieldErrorTarget& target, const FieldPointErrors& errors);

/// @brief Held-out field error of a deformed model.
/// @param rest, deformed  models (same SH degree)
/// @param restPoints      [P,3] X
/// @param warpedPoints    [P,3] x = phi(X)
/// @param rotations       [P,9] row-major R_p rotating the rest SH to the warped frame; null = identity
/// @param options         cutoff and filter for both evaluations; options.device says where
///                        they run (evaluateFeaturesOn())
FieldErrorReport fieldError(const GaussianCloud& rest, const GaussianCloud& deformed, const float* restPoints,
                            const float* warpedPoints, const float* rotations, std::size_t p,
                            const FeatureOptions& options = {});

} // namespace splatwarp
