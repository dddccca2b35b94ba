#pragma once
/// @file Metrics.h
/// @brief Image quality metrics: PSNR and SSIM (Wang et al. 2004) on the colour channels.
/// @note  Both compare the first min(3, channels) channels (alpha is ignored) of two images of
///        the same size, with values expected on [0, dynamicRange].
#include "image/Image.h"

namespace splatwarp {

/// @brief Options for ssim(); defaults are those of Wang et al. 2004.
struct SsimOptions {
    int window = 11;           ///< Gaussian window edge (pixels, odd)
    double sigma = 1.5;        ///< Gaussian window standard deviation (pixels)
    double k1 = 0.01;          ///< C1 = (k1 L)^2
    double k2 = 0.03;          ///< C2 = (k2 L)^2
    double dynamicRange = 1.0; ///< L: the value range of the data
};

/// @brief Peak signal-to-noise ratio 10 log10(peak^2 / MSE) in dB over all pixels and colour
///        channels; +infinity for identical images.
/// @throws InputError when the sizes differ or an image has no pixels.
double psnr(const Image& a, const Image& b, double peak = 1.0);

/// @brief Mean structural similarity: the SSIM map over every window position that fits inside
///        the image ("valid" region, as Wang's reference code), averaged, then averaged over channels.
/// @throws InputError when the sizes differ or the image is smaller than the window.
double ssim(const Image& a, const Image& b, const SsimOptions& options = {});

} // namespace splatwarp
