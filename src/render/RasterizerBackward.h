#pragma once
/// @file RasterizerBackward.h
/// @brief The CPU splat rasteriser made differentiable: a forward render that keeps its tile
///        bins and per-pixel state, and the backward pass from dLoss/dImage to every Gaussian's raw
///        parameters (mean, log-scale, quaternion, opacity logit, SH). Deterministic: per-pixel
///        terms are summed per tile entry inside one thread, then per Gaussian in entry order.
/// @note  The SH colour's dependence on the view direction is not carried to the mean: a small
///        term (3DGS keeps it), left out to keep the backward pass short.
#include <vector>

#include "core/GaussianCloud.h"
#include "render/Rasterizer.h"
#include "render/TileRaster.h"

namespace splatwarp {

/// @brief Gradients with the layout of GaussianCloud's arrays, plus what densification needs.
struct CloudGradients {
    std::vector<float> means;      ///< [N,3]
    std::vector<float> logScales;  ///< [N,3]
    std::vector<float> rotations;  ///< [N,4] w.r.t. the raw (unnormalised) quaternion
    std::vector<float> opacities;  ///< [N] w.r.t. the logit
    std::vector<float> sh;         ///< [N,K,3]
    std::vector<float> screenNorm; ///< [N] |dL/d(mean in NDC)| = |(dL/du W/2, dL/dv H/2)|, per view summed
    std::vector<int> visible;      ///< [N] views in which the Gaussian covered a tile
    /// @brief Zero gradients sized for `cloud`.
    void reset(const GaussianCloud& cloud);
};

/// @brief A forward render and what its backward pass needs.
struct RenderTape {
    Image image; ///< RGBA, equal to renderGaussians() of the same inputs
    detail::TileBins bins;
    detail::PixelState state;
    PinholeView view;
    Vec3f background;
};

/// @brief renderGaussians() keeping the tape. @throws InputError as renderGaussians().
RenderTape renderForTraining(const GaussianCloud& cloud, const Camera& camera, const RenderOptions& options = {});

/// @brief Add dLoss/dParameters of one render to `grads` (sized by reset()).
/// @param dImage [H,W,3] dLoss/dRGB of tape.image (alpha has no gradient).
void renderBackward(const GaussianCloud& cloud, const RenderTape& tape, const std::vector<float>& dImage,
                    CloudGradients& grads, bool threaded = true);

} // namespace splatwarp
