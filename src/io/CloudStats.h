#pragma once
/// @file CloudStats.h
/// @brief Summary statistics of a Gaussian cloud (what `splatwarp info` prints).
#include <cstddef>
#include <string>
#include <vector>

#include "core/GaussianCloud.h"

namespace splatwarp {

/// @brief Statistics over the finite values of a cloud; activated quantities as in 3DGS.
/// @note  Every field is 0 for an empty cloud (or when no finite value exists).
struct CloudStats {
    std::size_t count = 0;
    int shDegree = 0;
    Vec3d bboxMin{0, 0, 0}, bboxMax{0, 0, 0};    ///< bounding box of the finite centres
    double opacityMin = 0, opacityMean = 0, opacityMax = 0; ///< sigmoid(logit) over Gaussians
    double scaleMin = 0, scaleMedian = 0, scaleMax = 0;     ///< exp(logScale) over all 3N axes
    double quatNormMin = 0, quatNormMax = 0;     ///< |q| of the raw quaternions
    std::size_t invalidValues = 0;               ///< NaN/Inf values anywhere in the cloud
};

/// @brief Something in a cloud other commands refuse, drop or may render badly.
struct CloudWarning {
    std::string kind;      ///< "non-finite", "unnormalised-quaternions", "extreme-scales", "far-centres", "giant-gaussians", "extreme-extent"
    std::size_t count = 0; ///< Gaussians (or values, for non-finite) concerned
    std::string message;   ///< one line for the user
};

/// @brief Warnings for what a cloud holds: NaN/Inf values, quaternions far from unit length (or
///        near zero), scales far beyond the centres' extent (or below 1e-6 of it), centres far
///        from the rest and Gaussians wider than half of it (outlierWarnings()), centres beyond 1e6 units (float precision). `info`
///        prints them and lists them in --json.
std::vector<CloudWarning> cloudWarnings(const GaussianCloud& g, const CloudStats& stats);

/// @brief The "far-centres" and "giant-gaussians" warnings (core/Outliers.h), those that apply:
///        what `info` says and `deform` prints and reports of a model.
std::vector<CloudWarning> outlierWarnings(const GaussianCloud& g);

/// @brief Compute the statistics (double precision accumulation).
/// @param threaded run the per-Gaussian reduction with oneTBB (same result as serial up to the
///        order of the opacity sum).
CloudStats computeCloudStats(const GaussianCloud& g, bool threaded = true);

} // namespace splatwarp
