#pragma once
/// @file CurveSplit.h
/// @brief Split the Gaussians that Stage I's single affine map cannot bend, in the rest pose, and
///        move the children with Stage I again, so each child follows the deformation's curve with
///        its own map. How bent a Gaussian is: phi's second-order term over one sigma of one of its
///        axes (stageOneBending()), in its deformed sigmas; a flat Gaussian of a bent sheet, whose
///        one affine copy leaves the curved surface at its ends, is bent by several of its (thin)
///        sigmas. A split halves the bend; it pays when the L1 it saves on the Gaussian's mass exceeds
///        what the split costs (the children's own L1 and the mass the dimmer children lose to the
///        1/255 cutoff), and the Gaussians are split in order of that gain, within a budget. Where
///        the budget is spent, CurveSplitOptions::pruneWorth (off by default) lets a split remove the
///        faintest Gaussians to make room.
///
///        The children of a Gaussian bent by at most kFanAbove (more are fanned, curveSplitPattern()):
///        three along the bent axis at mean + {-d, 0, +d} sigma, that axis' sigma times
///        kCurveChildSigma (halving the second-order term), amplitudes alpha times
///        kCurveOuterWeight / kCurveCentreWeight, the parent's rotation, other scales and SH. The
///        weights and d minimise the children's L1 distance to the parent along the axis (1.15% of
///        its mass; scripts/curve-split-weights.py derives them); the field is a plain sum, so the
///        other axes are untouched.
#include <cstddef>
#include <optional>
#include <cstdint>
#include <vector>

#include "core/GaussianCloud.h"
#include "core/GaussianSplit.h"
#include "deform/DeformationGraph.h"
#include "deform/NodeTransforms.h"
#include "deform/StageOne.h"

namespace splatwarp {

constexpr double kCurveChildSigma = 0.70710678; ///< sqrt(1/2): the second-order term halves
constexpr double kCurveOffset = 1.0108;         ///< outer children at mean +- this x sigma
constexpr double kCurveOuterWeight = 0.3136;    ///< outer children's alpha / parent's
constexpr double kCurveCentreWeight = 0.7784;   ///< centre child's alpha / parent's
constexpr double kCurveSplitL1 = 0.0115;        ///< the children's L1 distance from the parent / its mass

/// A Gaussian bent by more than this many sigmas is fanned (see curveSplitPattern()) instead of split
/// in three: three rounds of halving cannot bring it down (playbot-31k bend: the 113 Gaussians bent
/// by 8 sigmas or more hold 17% of Stage I's error; docs/lab/fidelity-study.md).
constexpr double kFanAbove = 4.0;
constexpr double kFanChildBend = 0.5;  ///< a fan's children are bent by about this much
constexpr double kFanMinSigma = 0.15;  ///< nor thinner along the axis than this x the parent's sigma

/// @brief When and how much to split (deform --curve-split).
struct CurveSplitOptions {
    int rounds = 3;         ///< children are checked again, up to this many times
    /// At most this x the model's Gaussians are added (most bent first). 1.25, not 1: playbot-31k
    /// twist 0.637 -> 0.556 of Stage I at 2.25x the model (1.5: 0.530 at 2.5x; boundary weight 1).
    float maxAdded = 1.25f;
    /// When set, replaces maxAdded: at most this many Gaussians added (`--max-gaussians`).
    std::optional<std::size_t> maxAddedCount;
    double fanAbove = kFanAbove; ///< fan the Gaussians bent by more (<= 0: split every one in three)
    /// > 0: where the budget is spent, a split may still be made by removing the faintest unsplit
    /// Gaussians (least visible alpha times mean projected area first), while each one's cost times
    /// this is below the split's gain per Gaussian added, both in a view's units. 0 (default): never.
    /// At 1.5x, 3 brings guitar twist's judged field error from 0.0812 to 0.0688 (2.25x without:
    /// 0.0705) but costs 1.1 dB on the stripes mesh's bend in images (docs/lab/gaussian-budget.md).
    double pruneWorth = 0.0;
    bool threaded = true;
};

/// @brief Stage I's model with every bent Gaussian replaced by its children (in place: the
///        centre child takes the parent's slot, the outer ones are appended).
struct CurveSplitResult {
    GaussianCloud deformed;
    std::vector<std::uint8_t> moving;  ///< [N'] Stage I's moving flag (children: their own)
    std::vector<std::int32_t> parent;  ///< [N'] the rest Gaussian each one comes from
    std::vector<float> curve;          ///< [N',3] phi's second-order offset sum_a h_a (StageOneBends)
    std::size_t split = 0, added = 0;  ///< Gaussians split (every round) and Gaussians added
    std::size_t pruned = 0;            ///< Gaussians removed to make room for children (pruneWorth)
    int rounds = 0;                    ///< rounds that split something
    /// Gaussians bent beyond fanAbove where a round chose its splits; 0: the split is the one
    /// fanAbove 0 makes (every pattern and gain the same), so a run without fans need not be made.
    std::size_t beyondFan = 0;
    double ms = 0;
};

/// @brief The split pattern (core/GaussianSplit.h) for a Gaussian bent by `bend` of its sigmas,
///        along its bent axis: the children's sigma t along it (in the parent's sigmas; the
///        second-order term scales by t^2), their offsets and amplitudes (times the parent's), the
///        one at the mean first. Bend <= fanAbove: the three L1-closest children (file comment).
///        Above: a fan, t = max(kFanMinSigma, sqrt(kFanChildBend / bend)), children every 1.25 t
///        out to 3 sigma, amplitudes 1.25 N(u; 0, 1 - t^2) (the parent is the 1/t-scaled integral
///        of N(u; 0, 1 - t^2) times a Gaussian of sigma t at u; the ripple of that sum at 1.25 t is
///        below 1e-4). fanAbove <= 0: never a fan.
SplitPattern curveSplitPattern(double bend, double fanAbove = kFanAbove);

/// @brief How Stage I bends each Gaussian of a model (static ones: 0).
struct StageOneBends {
    std::vector<float> bend;          ///< [N] the largest stageOneBending() over its axes
    std::vector<std::uint8_t> axis;   ///< [N] that axis
    std::vector<float> curve;         ///< [N,3] sum_a h_a of stageOneCurvature(), world units
};

/// @brief The bending of each Gaussian of `rest` moved by Stage I (deformed, moving as
///        applyStageOneCpu() returned them).
StageOneBends stageOneBendingOf(const GaussianCloud& rest, const StageOneRig& rig, const DeformationGraph& graph,
                                const NodeTransforms& transforms, const GaussianCloud& deformed,
                                const std::vector<std::uint8_t>& moving, const StageOneOptions& stage1);

/// @brief The curve shift: `deformed` with every mean moved by `share` times its second-order
///        offset sum_a h_a (curve [N,3], StageOneBends or CurveSplitResult). phi moves a
///        Gaussian's mass by h_a on average (E[x_a^2] = sigma_a^2) while Stage I keeps the skinned
///        centre; for one Gaussian bent by b <= 1 of its sigmas the L1-closest shift is about
///        0.45 h (scripts/curve-shift-l1.py), but overlapping models prefer more.
GaussianCloud curveShifted(GaussianCloud deformed, const std::vector<float>& curve, double share);

/// @brief Split the bent Gaussians of Stage I's result (see the file comment), on the CPU.
CurveSplitResult curveSplit(const GaussianCloud& rest, const StageOneRig& rig, const DeformationGraph& graph,
                            const NodeTransforms& transforms, const std::vector<std::uint8_t>& nodeMoving,
                            const StageOneResult& stage1, const StageOneOptions& stage1Options,
                            const CurveSplitOptions& options);

} // namespace splatwarp
