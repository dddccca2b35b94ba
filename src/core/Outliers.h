#pragma once
/// @file Outliers.h
/// @brief The bulk of a model, and the few Gaussians far outside it: centres far from the rest
///        (far floaters of a trained model, stray points of a capture) and giants wider than half
///        the bulk (a sky, a blur). A handful of either set the box that `deform` spends --cells
///        on, and far centres the box a spec's "bbox" units are read in: 20 floaters 60 units from
///        the 4-unit stripes bar, or 3 faint Gaussians of sigma 20 around it, leave the bar a few
///        of its 64 cells (judged 0.1155 and 0.2199 after Stage II, against 0.0277 without them).
///        `info` and `deform` warn of them, `convert --drop-outliers` drops them.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/GaussianCloud.h"

namespace splatwarp {

/// Fraction of centres left out at each end of each axis when bounding the bulk (the orbit
/// cameras' default too: a few far floaters do not shrink the model to a dot).
constexpr double kBulkQuantile = 0.01;
/// A giant's largest standard deviation is over this fraction of the bulk's size. The shared
/// models' largest are 0.06-0.20 of theirs.
constexpr double kGiantSigma = 0.5;

/// @brief Quantile q of one coordinate of the finite centres (0 for a cloud without any).
double centreQuantile(const GaussianCloud& g, int axis, double q);

/// @brief The bulk's box and the Gaussians far outside it.
struct Outliers {
    Vec3d bulkLo{0, 0, 0}, bulkHi{0, 0, 0}; ///< per axis the kBulkQuantile and 1 - kBulkQuantile quantiles
    double bulkSize = 0;                    ///< the bulk box's largest side
    double boxRatio = 1;                    ///< the finite centres' box's largest side over bulkSize
    double largestSigma = 0;                ///< the largest finite standard deviation
    std::vector<std::uint8_t> far;          ///< [N] 1: the centre lies more than bulkSize outside the bulk box on an axis
    std::vector<std::uint8_t> giant;        ///< [N] 1: a standard deviation over kGiantSigma x bulkSize
    std::size_t farCount = 0, giantCount = 0;

    /// 1 where far or giant (what `convert --drop-outliers` drops)
    std::vector<std::uint8_t> either() const;
};

/// @brief Find the outliers. A bulk of one point (bulkSize 0) has none; non-finite values are
///        never outliers (the readers refuse or drop them).
Outliers findOutliers(const GaussianCloud& g);

} // namespace splatwarp
