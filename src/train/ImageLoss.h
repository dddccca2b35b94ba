#pragma once
/// @file ImageLoss.h
/// @brief The 3DGS training loss (1 - lambda) L1 + lambda (1 - SSIM) of a render against a
///        picture, with its gradient w.r.t. the render's RGB.
/// @note  The SSIM here is 3DGS's: an 11-tap Gaussian window (sigma 1.5) with zero padding, the
///        map averaged over every pixel ("same" size). image/Metrics.h's ssim() is Wang's "valid"
///        variant, used for reports; the two differ near the borders only.
#include <vector>

#include "image/Image.h"

namespace splatwarp {

/// @brief Loss value and dLoss/dRGB.
struct ImageLossResult {
    double loss = 0, l1 = 0, ssim = 0;
    std::vector<float> gradient; ///< [H,W,3] w.r.t. the render's first three channels
};

/// @brief (1 - lambda) mean|x - y| + lambda (1 - SSIM(x, y)) over RGB of two images of one size.
/// @param render the differentiated image x (3 or 4 channels, alpha ignored)
/// @param target the picture y (3 or 4 channels, alpha ignored)
/// @param lambda the D-SSIM weight (3DGS: 0.2)
/// @throws InputError when the sizes differ.
ImageLossResult imageLoss(const Image& render, const Image& target, double lambda = 0.2, bool threaded = true);

} // namespace splatwarp
