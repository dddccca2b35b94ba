#pragma once
/// @file SplatProjection.h
/// @brief Per-Gaussian projection (EWA splatting) and per-pixel alpha of the 3DGS rasteriser,
///        shared by the CPU rasteriser and the CUDA one (one source of truth).
/// @note  Pixel convention: pixel (i, j) covers [i, i+1) x [j, j+1) and is sampled at its centre
///        (i + 0.5, j + 0.5); a camera point projects to u = fx x/z + cx, v = fy y/z + cy
///        (OpenCV axes: x right, y down, z forward). With cx = width/2 the image is symmetric.
#include "core/HostDevice.h"
#include "core/SmallMath.h"
#include "field/GaussianMath.h"
#include "sh/SphericalHarmonics.h"

namespace splatwarp {

/// Means closer than this (camera z) are culled, as in 3DGS: the EWA Jacobian explodes near z = 0.
constexpr float kSplatNearPlane = 0.2f;
/// Screen-space low-pass filter added to the 2D covariance diagonal (pixels^2): every splat
/// covers at least about one pixel, which removes aliasing of sub-pixel Gaussians (3DGS value).
constexpr float kSplatDilation = 0.3f;
/// Alpha is capped below 1 so the transmittance never reaches exactly zero (3DGS value).
constexpr float kSplatMaxAlpha = 0.99f;
/// Contributions below one 8-bit step are skipped (the same cutoff as the field code).
constexpr float kSplatMinAlpha = kDefaultCutoff;
/// Compositing stops once the transmittance would fall below this (3DGS value).
constexpr float kSplatMinTransmittance = 1e-4f;
/// Screen extent of a splat in standard deviations of its largest 2D axis.
constexpr float kSplatExtentSigmas = 3.0f;
/// The Jacobian is evaluated with x/z, y/z clamped to 1.3x the half field of view: Gaussians far
/// outside the view otherwise get huge, wrong footprints (3DGS value).
constexpr float kSplatFrustumSlack = 1.3f;
/// Edge of the square screen tiles that group splats for compositing.
constexpr int kSplatTileSize = 16;

/// @brief Camera data needed per Gaussian, in float (what a CUDA kernel receives).
struct PinholeView {
    Mat3f rotation = Mat3f::identity(); ///< world-to-camera
    Vec3f translation;                  ///< x_cam = rotation * x_world + translation
    Vec3f centre;                       ///< camera centre in world space (-rotation^T translation)
    float fx = 0, fy = 0, cx = 0, cy = 0;
    int width = 0, height = 0;
};

/// @brief A Gaussian projected to the screen.
struct ProjectedSplat {
    float u = 0, v = 0;                     ///< mean in pixel coordinates (see the file note)
    float conicA = 0, conicB = 0, conicC = 0; ///< inverse 2D covariance [[A, B], [B, C]]
    float depth = 0;                        ///< camera-space z of the mean (sort key)
    float radius = 0;                       ///< kSplatExtentSigmas * sqrt(largest eigenvalue), pixels
    float opacity = 0;                      ///< activated opacity
    /// Half extents (pixels) of the box outside which alpha < kSplatMinAlpha: a pure speed-up for
    /// per-pixel loops (the alpha test would reject those pixels anyway); 0 when it never reaches it.
    float cutoffX = 0, cutoffY = 0;
    /// Exponent below which alpha < kSplatMinAlpha: ln(kSplatMinAlpha / opacity), skips the exp.
    float minPower = 0;
};

/// @brief EWA projection J W Sigma W^T J^T (+ kSplatDilation on the diagonal) of one Gaussian.
/// @param cov world-space 3D covariance; @param opacity activated opacity.
/// @return false when the Gaussian is culled (behind the near plane or degenerate).
SPLATWARP_HOST_DEVICE bool projectSplat(const PinholeView& view, const Vec3f& mean, const Mat3f& cov, float opacity,
                                        ProjectedSplat& out)
{
    const Vec3f t = view.rotation * mean + view.translation;
    if (!(t.z > kSplatNearPlane)) return false;
    const float limX = kSplatFrustumSlack * 0.5f * float(view.width) / view.fx;
    const float limY = kSplatFrustumSlack * 0.5f * float(view.height) / view.fy;
    const float invZ = 1.0f / t.z;
    // Plain comparisons rather than fmin/fmax: no NaN handling needed, and they inline everywhere.
    const float txz = t.x * invZ < -limX ? -limX : (t.x * invZ > limX ? limX : t.x * invZ);
    const float tyz = t.y * invZ < -limY ? -limY : (t.y * invZ > limY ? limY : t.y * invZ);
    // Rows of J W (2 x 3): the Jacobian of the perspective map at t, times the view rotation.
    Vec3f jw0, jw1;
    for (int c = 0; c < 3; ++c) {
        jw0[c] = view.fx * invZ * (view.rotation.m[0][c] - txz * view.rotation.m[2][c]);
        jw1[c] = view.fy * invZ * (view.rotation.m[1][c] - tyz * view.rotation.m[2][c]);
    }
    const Vec3f s0 = cov * jw0, s1 = cov * jw1;
    const float a = dot(jw0, s0) + kSplatDilation;
    const float b = dot(jw0, s1);
    const float c = dot(jw1, s1) + kSplatDilation;
    const float det = a * c - b * b;
    if (!(det > 0.0f)) return false;
    const float invDet = 1.0f / det;
    out.u = view.fx * t.x * invZ + view.cx;
    out.v = view.fy * t.y * invZ + view.cy;
    out.conicA = c * invDet;
    out.conicB = -b * invDet;
    out.conicC = a * invDet;
    out.depth = t.z;
    const float mid = 0.5f * (a + c);
    const float disc = mid * mid - det;
    const float lambdaMax = mid + std::sqrt(disc > 0.0f ? disc : 0.0f);
    out.radius = kSplatExtentSigmas * std::sqrt(lambdaMax);
    out.opacity = opacity;
    // The alpha >= cutoff ellipse (Mahalanobis radius m) has the box m sqrt(a) x m sqrt(c); the small
    // margin keeps float rounding at its edge from dropping a pixel the alpha test would keep.
    const float m = extentRadius(opacity, kSplatMinAlpha);
    out.cutoffX = m > 0.0f ? m * std::sqrt(a) * 1.0001f + 1e-3f : 0.0f;
    out.cutoffY = m > 0.0f ? m * std::sqrt(c) * 1.0001f + 1e-3f : 0.0f;
    // Slightly below the exact bound, so rounding never rejects what the final alpha test keeps.
    out.minPower = m > 0.0f ? -0.5f * m * m * 1.0001f : 0.0f;
    return true;
}

/// @brief Inclusive range of pixels whose centres lie within the splat's screen extent, clamped
///        to the image; false when it misses the image.
SPLATWARP_HOST_DEVICE bool splatPixelRange(const ProjectedSplat& s, int width, int height, int& x0, int& y0, int& x1,
                                           int& y1)
{
    // Pixel i is sampled at i + 0.5, so it is inside when |i + 0.5 - u| <= radius.
    const float fx0 = std::ceil(s.u - s.radius - 0.5f), fx1 = std::floor(s.u + s.radius - 0.5f);
    const float fy0 = std::ceil(s.v - s.radius - 0.5f), fy1 = std::floor(s.v + s.radius - 0.5f);
    if (fx1 < 0.0f || fy1 < 0.0f || fx0 > float(width - 1) || fy0 > float(height - 1) || fx0 > fx1 || fy0 > fy1)
        return false;
    x0 = fx0 < 0.0f ? 0 : int(fx0);
    y0 = fy0 < 0.0f ? 0 : int(fy0);
    x1 = fx1 > float(width - 1) ? width - 1 : int(fx1);
    y1 = fy1 > float(height - 1) ? height - 1 : int(fy1);
    return true;
}

/// @brief An inclusive box of pixels (or tiles); empty when x1 < x0.
struct PixelBox {
    int x0 = 0, y0 = 0, x1 = -1, y1 = -1;
};

/// @brief Project a Gaussian for a tiled rasteriser (the CPU and the CUDA one): projectSplat(),
///        the pixel range that assigns it to tiles (splatPixelRange()) and the box of pixels where
///        its alpha can reach kSplatMinAlpha (a pure speed-up: splatAlpha() rejects the others).
/// @param opacity activated opacity
/// @return false, leaving the boxes empty, when the splat covers no pixel: culled, never reaching
///         the alpha cutoff, or off screen.
SPLATWARP_HOST_DEVICE bool projectSplatOnScreen(const PinholeView& view, const Vec3f& mean, const Mat3f& cov,
                                                float opacity, ProjectedSplat& out, PixelBox& range, PixelBox& reach)
{
    range = PixelBox();
    reach = PixelBox();
    if (!projectSplat(view, mean, cov, opacity, out) || out.cutoffX <= 0.0f ||
        !splatPixelRange(out, view.width, view.height, range.x0, range.y0, range.x1, range.y1))
        return false; // splatPixelRange() writes the range only when it succeeds
    reach.x0 = int(std::ceil(out.u - out.cutoffX - 0.5f));
    reach.x1 = int(std::floor(out.u + out.cutoffX - 0.5f));
    reach.y0 = int(std::ceil(out.v - out.cutoffY - 0.5f));
    reach.y1 = int(std::floor(out.v + out.cutoffY - 0.5f));
    return true;
}

/// @brief Alpha of a splat at a pixel-space point: min(kSplatMaxAlpha, opacity exp(-1/2 d^T conic d)),
///        or 0 where it is below kSplatMinAlpha.
SPLATWARP_HOST_DEVICE float splatAlpha(const ProjectedSplat& s, float px, float py)
{
    const float dx = px - s.u, dy = py - s.v;
    const float power = -0.5f * (s.conicA * dx * dx + s.conicC * dy * dy) - s.conicB * dx * dy;
    // power > 0 only comes from rounding of a near-singular conic.
    if (power > 0.0f || power < s.minPower) return 0.0f;
    const float value = s.opacity * std::exp(power);
    const float alpha = value < kSplatMaxAlpha ? value : kSplatMaxAlpha;
    return alpha < kSplatMinAlpha ? 0.0f : alpha;
}

/// @brief View-dependent colour of a Gaussian: the SH evaluated along camera centre -> mean.
SPLATWARP_HOST_DEVICE Vec3f splatColour(const PinholeView& view, int shDegree, const float* coeffs, const Vec3f& mean)
{
    return evalShColor<float>(shDegree, coeffs, mean - view.centre);
}

} // namespace splatwarp
