#pragma once
/// @file MomentInit.h
/// @brief Gaussians from the local moments of a sampled density (the `from-vdb` initialisation
///        and its `--no-fit` baseline): the voxels are split into clusters, heaviest first, and
///        each cluster becomes the Gaussian with its mass, mean and covariance.
#include <cstddef>
#include <vector>

#include "core/GaussianCloud.h"

namespace splatwarp {

/// @brief Voxels of a volume as flat arrays. V = values.size(), K = (shDegree+1)^2.
struct VoxelSamples {
    double voxelSize = 0.0;       ///< edge of a voxel (world units)
    int shDegree = 0;             ///< degree of the features
    std::vector<float> positions; ///< [V,3] voxel centres (world)
    std::vector<float> values;    ///< [V]   field value O (>= 0)
    std::vector<float> features;  ///< [V,K,3] radial SH features F (F = O * colour coefficients)
    std::size_t size() const { return values.size(); }
};

/// @brief Options of initFromMoments().
struct MomentInitOptions {
    std::size_t gaussians = 0; ///< budget N; 0: one per 8 voxels
    /// Standard deviations are the moments' times this factor: clusters tile space, so Gaussians of
    /// exactly their cluster's moments leave dips between them.
    double spread = 1.0;
    float maxAlpha = 0.99f;    ///< a cluster whose mass needs more opacity gets a wider Gaussian instead
    /// The isotropic filter variance the values were blurred with (our own to-vdb files: their rest
    /// filter, which keeps alpha and adds this to every variance): alpha comes from the filtered
    /// moments, the covariance with it taken off (down to the one-voxel floor).
    double filterVariance = 0.0;
};

/// @brief The default budget: one Gaussian per 8 voxels (at least 1).
std::size_t defaultGaussianBudget(std::size_t voxels);

/// @brief Place up to N Gaussians on the voxels.
/// @details Clusters start as all voxels; the cluster of largest mass (sum of values) is split at
///          its median along its widest axis until there are N clusters (or none can split).
///          Each cluster with mass M > 0 gives a Gaussian: mean = value-weighted mean, covariance =
///          value-weighted covariance (each axis at least voxelSize^2/12) scaled by spread^2,
///          alpha = M voxelSize^3 / ((2 pi)^{3/2} sqrt(det Sigma)) (so the integral of alpha G is
///          the cluster's mass), SH = the cluster's features per unit value; then filterVariance is
///          taken off every axis of Sigma.
/// @throws InputError for inconsistent arrays or a non-positive voxel size.
GaussianCloud initFromMoments(const VoxelSamples& voxels, const MomentInitOptions& options = {});

} // namespace splatwarp
