#pragma once
/// @file GaussianSplit.h
/// @brief The one split of the project: a Gaussian becomes several along one of its own axes, by a
///        pattern of offsets, widths and opacities. Each place that splits names its rule as a
///        pattern: Stage II's keep-moments pair and from-vdb's shrink pair (stage2/Densify.h), the
///        curve split's three and its fans (deform/CurveSplit.h), the validated split's three.
#include <cstddef>
#include <vector>

#include "core/GaussianCloud.h"

namespace splatwarp {

/// @brief How the children of one Gaussian sit along one of its axes.
struct SplitPattern {
    double sigma = 1.0;          ///< the children's sigma along the axis, times the parent's
    std::vector<double> offsets; ///< their distances from the mean along the axis, in the parent's sigmas
    std::vector<double> weights; ///< their alpha, times the parent's (1: the parent's opacity as it is)
};

/// @brief The index (0..2) of Gaussian i's largest scale (the first of equal ones).
int longestAxis(const GaussianCloud& g, std::size_t i);

/// @brief The children of Gaussian i of g along its own axis (0..2), appended to out (same SH
///        degree) in the pattern's order; each is a copy of i but for its mean, its log-scale along
///        the axis and its opacity. Returns how many.
std::size_t appendSplitChildren(const GaussianCloud& g, std::size_t i, int axis, const SplitPattern& pattern,
                                GaussianCloud& out);

} // namespace splatwarp
