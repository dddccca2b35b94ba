#pragma once
/// @file Extinction.h
/// @brief `from-vdb --as extinction`: Gaussians fitted to an extinction coefficient sigma(x)
///        (per world unit) get the splat opacity whose ray through their centre has the same
///        transmittance.
/// @details A Gaussian of density rho G(x) has optical depth along a ray through its centre in
///          direction d of tau(d) = rho sqrt(2 pi) / sqrt(d^T Sigma^-1 d), and along a parallel ray
///          at screen offset u exactly tau(d) G2(u) (G2 = the projected 2D Gaussian the rasteriser
///          draws). A splat of opacity alpha transmits 1 - alpha G2(u). We take
///          alpha = 1 - exp(-tau) with tau at the geometric-mean standard deviation
///          s = (s1 s2 s3)^{1/3} (view independent), so:
///          - the centre ray is exact for a sphere, and off by the axis ratio for elongated Gaussians;
///          - off centre 1 - alpha G2 >= exp(-tau G2): thin (tau << 1) splats are exact, opaque ones
///            transmit too much at their skirt;
///          - overlapping splats composite as prod(1 - alpha_i G2_i) vs exp(-sum tau_i G2_i): the
///            same per-splat error, compounded. alpha is capped at the rasteriser's 0.99 (tau 4.6).
///          Measured in tests/fit/ExtinctionTest.cpp (uniform slab vs exp(-sigma L)) and docs/benchmarks.md.
#include "core/GaussianCloud.h"

namespace splatwarp {

/// @brief Optical depth through the centre of Gaussian i of `cloud` when its alpha means density
///        alpha * densityScale (per world unit): tau = rho sqrt(2 pi) (s1 s2 s3)^{1/3}.
double centreOpticalDepth(const GaussianCloud& cloud, std::size_t i, double densityScale);

/// @brief Convert a cloud fitted to sigma / densityScale (alpha_i = rho_i / densityScale) into
///        splat opacities alpha_i = 1 - exp(-tau_i), capped at 0.99.
/// @return the number of splats whose opacity hit the cap
std::size_t extinctionToOpacity(GaussianCloud& cloud, double densityScale);

/// @brief Inverse of extinctionToOpacity(): splat opacities back to alpha_i = rho_i / densityScale
///        (clamped to (0, 1); capped splats come back at the cap's density).
void opacityToExtinction(GaussianCloud& cloud, double densityScale);

} // namespace splatwarp
