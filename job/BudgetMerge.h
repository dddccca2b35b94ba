#pragma once
/// @file BudgetMerge.h
/// @brief The Gaussian budget spent after the fit (`--budget-merge auto`): the splits before
///        Stage II add their own share, Stage II fits the children, and then the families of
///        children that buy least are merged back into one Gaussian each until the model fits
///        `--max-gaussians`. A split's worth is measured on the fitted model (the exact change of
///        the validation score when its family becomes one Gaussian), not predicted before the fit;
///        a merge keeps the family's mass, so nothing faint is dropped (the prune that does costs
///        the image judge: docs/lab/gaussian-budget.md).
#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/GaussianCloud.h"
#include "job/Judge.h"

namespace splatwarp {

/// @brief What the merge did.
struct BudgetMergeReport {
    std::size_t limit = 0;     ///< the most Gaussians the output may hold
    std::size_t families = 0;  ///< Gaussians of the rest model that were split (two or more children)
    std::size_t merged = 0;    ///< families merged back into one Gaussian
    std::size_t mergedToRuns = 0; ///< families of more than three merged into runs of three
    std::size_t removed = 0;   ///< Gaussians removed by those merges
    double before = 0, after = 0; ///< validation score (opacity + colour relative L1)
    double ms = 0;
};

/// @brief One Gaussian with the mass, mean, covariance and mass-weighted SH of Gaussians `members`
///        of g together (the field's moments: mass alpha s0 s1 s2), appended to out. Alpha is held
///        below 1 (a family folded tighter than its parent would need more).
void appendMerged(const GaussianCloud& g, const std::vector<std::size_t>& members, GaussianCloud& out);

/// @brief The groups of Gaussians to merge so that `model` holds at most `limit`: a family (the
///        Gaussians of one rest Gaussian, `parent` [N]) is merged whole or, when larger than three,
///        first into runs of three along the line its members spread along (a Gaussian split twice
///        back to its first split's children); steps of least validation loss per Gaussian removed
///        first, each loss measured once on `model`. Each group lists its members in index order.
/// @throws UsageError when merging every family still leaves more than `limit`.
std::vector<std::vector<std::size_t>> groupsToMerge(const Judge& validation, const GaussianCloud& model,
                                                      const std::vector<std::int32_t>& parent, std::size_t limit,
                                                      BudgetMergeReport& report);

/// @brief `g` with each group merged into one Gaussian (appendMerged()) in its first member's slot,
///        the other members removed, the order of the rest kept.
GaussianCloud withGroupsMerged(const GaussianCloud& g, const std::vector<std::vector<std::size_t>>& groups);

/// @brief groupsToMerge() then withGroupsMerged() on `model`, the report's scores before and
///        after included.
GaussianCloud mergeToBudget(const Judge& validation, const GaussianCloud& model, const std::vector<std::int32_t>& parent,
                            std::size_t limit, BudgetMergeReport& report);

} // namespace splatwarp
