#pragma once
/// @file Densify.h
/// @brief Split and prune between Stage II rounds, on a host cloud with its moving flags and rest
///        cells (the arrays runStageTwo() takes), so every device follows the same rules.
///
///        The field is additive (field/FeatureField.h: O = sum alpha G, F = sum alpha G c, no
///        compositing), so a split can keep the parent's mass and moments exactly: two children
///        at mean +- k sigma u along the longest axis u, sigma_u' = sigma_u sqrt(1 - k^2), alpha' =
///        alpha / (2 sqrt(1 - k^2)), the parent's SH. Then the pair's integral of alpha G (and of
///        alpha G c per SH coefficient), mean and covariance are the parent's; the field pointwise
///        is not (one Gaussian becomes two bumps). Only the cutoff (pairs with alpha G below it are
///        not counted) makes it inexact: a few 1e-3 of the mass at the default 1/255.
///        With a low-pass filter (Stage II's training field) the filtered mass alpha |Sigma + V|^1/2
///        is kept only to first order in V / Sigma.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/GaussianCloud.h"
#include "core/GaussianSplit.h"

namespace splatwarp {

/// Children sit at mean +- kSplitOffset sigma along the axis: sigma' = 0.866 sigma, alpha' = 0.577 alpha.
/// The pair then differs from the parent pointwise by 2% of its mass in L1 (0.8, 3DGS's 1/1.6
/// shrink: 23%), which the unfiltered judge sees and Stage II, fitting the filtered field, hardly
/// undoes: guitar bend 0.945 with 0.5, 0.971 with 0.8 (docs/lab/fidelity-study.md#split-and-prune).
constexpr float kSplitOffset = 0.5f;
/// Largest offset: alpha' = alpha / (2 sqrt(1 - k^2)) stays below 1 for every parent up to sqrt(3)/2.
constexpr float kMaxSplitOffset = 0.85f;

/// @brief Stage II's split (the file comment): two children at mean +- k sigma u, sigma_u' =
///        sigma_u sqrt(1 - k^2), alpha' = alpha / (2 sqrt(1 - k^2)): the pair keeps the parent's
///        mass and moments. @throws InputError unless 0 < k <= kMaxSplitOffset.
SplitPattern keepMomentsSplit(float k = kSplitOffset);

/// @brief from-vdb's split, fitting from scratch (3DGS's kind): mean +- k sigma u, sigma_u' = 0.6
///        sigma_u, alpha unchanged (the pair adds mass the next round fits away). Measured with
///        `from-vdb wdas_cloud_sixteenth.vdb --rounds 3`: held-out error 0.0617 with it, 0.0628
///        with keepMomentsSplit(), so from-vdb keeps it. @throws InputError as keepMomentsSplit().
SplitPattern shrinkSplit(float k = kSplitOffset);

/// @brief A model with the per-Gaussian arrays a fit carries, kept in step by every change: the
///        split and the prune below, and the validated split (job/ValidatedSplit.h).
struct FitState {
    GaussianCloud& cloud;
    std::vector<std::uint8_t>& moving;       ///< [N] 1: Stage II moves it
    std::vector<std::int32_t>& gaussianCell; ///< [N] rest cell of its low-pass filter (-1: none)
    std::vector<float>* curve = nullptr;     ///< [N,3] phi's second-order offsets, when kept (deform's start)
    std::vector<std::int32_t>* parent = nullptr; ///< [N] the rest Gaussian each comes from, when kept (deform's start)

    /// @brief Gaussian i becomes row rows[0] of `from`, the other rows are appended; each takes i's
    ///        cell and parent, its moving flag from fromMoving and its curve row from fromCurve (both indexed
    ///        by the row of `from`; null: i's).
    void replace(std::size_t i, const GaussianCloud& from, const std::vector<std::size_t>& rows,
                 const std::uint8_t* fromMoving = nullptr, const float* fromCurve = nullptr);
};

/// @brief The moving Gaussians whose rest cell's F (cellGradient, [C,9]) has its largest singular
///        value above `stretch`, ascending. Gaussians without a cell (-1) are never chosen.
std::vector<std::size_t> stretchedGaussians(const std::vector<std::uint8_t>& moving,
                                            const std::vector<std::int32_t>& gaussianCell,
                                            const std::vector<float>& cellGradient, float stretch);

/// @brief Split Gaussian i along its longest axis by a pattern (core/GaussianSplit.h): i becomes
///        the first child, the others are appended with i's moving flag and cell.
void splitGaussian(FitState& d, std::size_t i, const SplitPattern& pattern = keepMomentsSplit());

/// @brief Split each listed Gaussian (indices into the cloud before any split); returns how many.
std::size_t splitGaussians(FitState& d, const std::vector<std::size_t>& which,
                           const SplitPattern& pattern = keepMomentsSplit());

/// @brief Remove the moving Gaussians whose opacity alpha is below `below` (the static ones and
///        every other moving one are kept bit for bit, in order); returns how many were removed.
std::size_t pruneMovingBelow(FitState& d, float below);

} // namespace splatwarp
