#pragma once
/// @file Extinction.h
/// @brief `from-vdb --as extinction`: Gaussians fitted to an extinction coefficient sigma(x)
///        (per world unit) get the view-independent splat opacity that absorbs their mass on
///        average over view directions.
/// @details A Gaussian of density rho G(x) has optical depth along a ray through its centre in
///          direction d of tau(d) = rho sqrt(2 pi) / sqrt(d^T Sigma^-1 d), and along a parallel ray
///          at screen offset u exactly tau(d) G2(u) (G2 = the projected 2D Gaussian the rasteriser
///          draws, of area A(d) = M / tau(d), M = rho (2 pi)^{3/2} s1 s2 s3 the Gaussian's mass). A
///          splat of opacity alpha transmits 1 - alpha G2(u) and, when thin, absorbs alpha A(d). One
///          view-independent alpha cannot match every d; we match the absorbed mass on average over
///          directions, alpha A_mean = M, i.e. tau = the harmonic mean over directions of tau(d)
///          = rho sqrt(2 pi) / R_G(1/s1^2, 1/s2^2, 1/s3^2) (Carlson's R_G: the mean of
///          sqrt(d^T Sigma^-1 d)), and alpha = 1 - exp(-tau). A sphere's centre ray is exact; a flat
///          Gaussian is too opaque face-on and too clear edge-on, less than with the former geometric
///          mean scale (s1 s2 s3)^{1/3}, which made the flat Gaussians of fitted slabs far too opaque.
///          Off centre 1 - alpha G2 >= exp(-tau G2): opaque splats transmit too much at their skirt;
///          overlapping splats compound it. alpha is capped at the rasteriser's 0.99 (tau 4.6).
///          Measured (FromVdb.ExtinctionSlabMatchesAnalyticTransmittance, uniform slab, sigma L = 1,
///          transmittance through the centre along z / x / (1,0,1) / (1,1,1), exact 0.368 / 0.041 /
///          0.243 / 0.177, default density scale): geometric mean 0.250 / 0.028 / 0.165 / 0.100,
///          this rule 0.362 / 0.038 / 0.222 / 0.141. smoke.vdb, 4 orbit views against the ray-marched
///          volume: 24.70 -> 26.04 dB; other candidates (R_F, harmonic mean of the scales, mean
///          transmittance, a dilogarithm map) in docs/lab/from-vdb.md, by scripts/extinction-rules.sh.
#include "core/GaussianCloud.h"

namespace splatwarp {

/// @brief Carlson's R_G(a, b, c): the mean over unit directions d of sqrt(a d1^2 + b d2^2 + c d3^2)
///        (a, b, c > 0).
double meanRootQuadratic(double a, double b, double c);

/// @brief The optical depth a splat's opacity stands for when Gaussian i's alpha means density
///        rho = alpha * densityScale (per world unit): the harmonic mean over directions of the
///        centre ray's depth, tau = rho sqrt(2 pi) / R_G(1/s1^2, 1/s2^2, 1/s3^2).
double splatOpticalDepth(const GaussianCloud& cloud, std::size_t i, double densityScale);

/// @brief Convert a cloud fitted to sigma / densityScale (alpha_i = rho_i / densityScale) into
///        splat opacities alpha_i = 1 - exp(-tau_i), capped at 0.99.
/// @return the number of splats whose opacity hit the cap
std::size_t extinctionToOpacity(GaussianCloud& cloud, double densityScale);

/// @brief Inverse of extinctionToOpacity(): splat opacities back to alpha_i = rho_i / densityScale
///        (clamped to (0, 1); capped splats come back at the cap's density).
void opacityToExtinction(GaussianCloud& cloud, double densityScale);

} // namespace splatwarp
