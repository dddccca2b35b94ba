#include "render/RasterizerBackward.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "core/Error.h"
#include "core/ParallelFor.h"
#include "field/GaussianMath.h"
#include "sh/SphericalHarmonics.h"

namespace splatwarp {

namespace {

using detail::ScreenSplat;
using detail::TileBins;

/// Slots of the screen quantities a splat's loss gradient is gathered in.
enum ScreenSlot { kU, kV, kConicA, kConicB, kConicC, kOpacity, kColour, kSlots = kColour + 3 };

/// dLoss w.r.t. one splat's screen quantities (ScreenSlot), summed over the pixels of one tile.
struct EntryGrad {
    float d[kSlots] = {};
};

/// Walk each tile's splats back to front (the mirror of the forward compositing): per pixel the
/// transmittance in front of the splat and the colour behind it, as 3DGS's per-pixel backward,
/// but splat by splat over the pixels it can reach, so each splat's sums stay in registers.
struct TileBackwardOp {
    const TileBins& bins;
    const detail::PixelState& state;
    const std::vector<float>& dImage;
    Vec3f background;
    int width, height;
    std::vector<EntryGrad>& out;
    void operator()(std::size_t beginTile, std::size_t endTile) const
    {
        constexpr int kPixels = kSplatTileSize * kSplatTileSize;
        float t[kPixels];
        Vec3f behind[kPixels], dC[kPixels];
        std::size_t stop[kPixels];
        for (std::size_t tile = beginTile; tile < endTile; ++tile) {
            const int tx0 = int(tile % std::size_t(bins.tilesX)) * kSplatTileSize;
            const int ty0 = int(tile / std::size_t(bins.tilesX)) * kSplatTileSize;
            const int tx1 = std::min(width, tx0 + kSplatTileSize) - 1, ty1 = std::min(height, ty0 + kSplatTileSize) - 1;
            std::size_t last = bins.tileStart[tile];
            for (int y = ty0; y <= ty1; ++y)
                for (int x = tx0; x <= tx1; ++x) {
                    const int k = (y - ty0) * kSplatTileSize + (x - tx0);
                    const std::size_t p = std::size_t(y) * std::size_t(width) + std::size_t(x);
                    t[k] = state.transmittance[p];
                    behind[k] = background;
                    dC[k] = Vec3f(dImage[3 * p], dImage[3 * p + 1], dImage[3 * p + 2]);
                    stop[k] = state.stopEntry[p];
                    last = std::max(last, stop[k]);
                }
            for (std::size_t e = last; e-- > bins.tileStart[tile];) {
                const ScreenSplat& s = bins.splats[std::uint32_t(bins.keys[e])];
                const int x0 = std::max(tx0, s.reach.x0), x1 = std::min(tx1, s.reach.x1);
                const int y0 = std::max(ty0, s.reach.y0), y1 = std::min(ty1, s.reach.y1);
                float g[kSlots] = {};
                for (int y = y0; y <= y1; ++y)
                    for (int x = x0; x <= x1; ++x) {
                        const int k = (y - ty0) * kSplatTileSize + (x - tx0);
                        if (e >= stop[k]) continue;
                        pixel(s, float(x) + 0.5f, float(y) + 0.5f, t[k], behind[k], dC[k], g);
                    }
                for (int k = 0; k < kSlots; ++k) out[e].d[k] = g[k];
            }
        }
    }
    /// One (splat, pixel) pair: gradients into g, the pixel's state moved in front of the splat.
    static void pixel(const ScreenSplat& s, float px, float py, float& t, Vec3f& behind, const Vec3f& dC, float* g)
    {
        const float alpha = splatAlpha(s.p, px, py);
        if (alpha == 0.0f) return;
        const float ti = t / (1.0f - alpha);
        for (int c = 0; c < 3; ++c) g[kColour + c] += alpha * ti * dC[c];
        const float dAlpha = ti * dot(dC, s.colour - behind);
        behind = s.colour * alpha + behind * (1.0f - alpha);
        t = ti;
        const float dx = px - s.p.u, dy = py - s.p.v;
        const float power = -0.5f * (s.p.conicA * dx * dx + s.p.conicC * dy * dy) - s.p.conicB * dx * dy;
        const float gauss = std::exp(power);
        if (s.p.opacity * gauss >= kSplatMaxAlpha) return; // clamped: alpha does not move
        const float dPower = dAlpha * alpha;
        g[kOpacity] += dAlpha * gauss;
        g[kU] += dPower * (s.p.conicA * dx + s.p.conicB * dy);
        g[kV] += dPower * (s.p.conicC * dy + s.p.conicB * dx);
        g[kConicA] += -0.5f * dPower * dx * dx;
        g[kConicC] += -0.5f * dPower * dy * dy;
        g[kConicB] += -dPower * dx * dy;
    }
};

/// d(rotation matrix of the normalised quaternion)/d(w, x, y, z), contracted with dR.
std::array<double, 4> quatMatrixGrad(const Quatf& q, const Mat3d& dR)
{
    const double n = std::sqrt(double(q.w) * q.w + double(q.x) * q.x + double(q.y) * q.y + double(q.z) * q.z);
    if (!(n > 0)) return {0, 0, 0, 0};
    const double w = q.w / n, x = q.x / n, y = q.y / n, z = q.z / n;
    const double (&d)[3][3] = dR.m;
    // Rows: d/dw, d/dx, d/dy, d/dz of the 9 entries of quatToMatrix().
    const double dq[4] = {
        2 * (-z * d[0][1] + y * d[0][2] + z * d[1][0] - x * d[1][2] - y * d[2][0] + x * d[2][1]),
        2 * (y * d[0][1] + z * d[0][2] + y * d[1][0] - 2 * x * d[1][1] - w * d[1][2] + z * d[2][0] + w * d[2][1] - 2 * x * d[2][2]),
        2 * (-2 * y * d[0][0] + x * d[0][1] + w * d[0][2] + x * d[1][0] + z * d[1][2] - w * d[2][0] + z * d[2][1] - 2 * y * d[2][2]),
        2 * (-2 * z * d[0][0] - w * d[0][1] + x * d[0][2] + w * d[1][0] - 2 * z * d[1][1] + y * d[1][2] + x * d[2][0] + y * d[2][1])};
    const double qn[4] = {w, x, y, z};
    const double along = dq[0] * w + dq[1] * x + dq[2] * y + dq[3] * z;
    std::array<double, 4> out;
    for (int k = 0; k < 4; ++k) out[k] = (dq[k] - qn[k] * along) / n; // through the normalisation
    return out;
}

/// Per-Gaussian sums of the entry gradients (ScreenSlot), in double.
struct SplatGrad {
    double d[kSlots] = {};
    bool any = false;
};

/// dL/dt (camera-space mean) through u, v and the Jacobian rows jw0, jw1 of projectSplat().
Vec3d cameraMeanGrad(const PinholeView& view, const Vec3d& t, const SplatGrad& g, const Vec3d& dJw0, const Vec3d& dJw1,
                     const Vec3d& jw0, const Vec3d& jw1)
{
    const double invZ = 1.0 / t.z;
    const double limX = kSplatFrustumSlack * 0.5 * view.width / view.fx, limY = kSplatFrustumSlack * 0.5 * view.height / view.fy;
    const bool freeX = std::abs(t.x * invZ) < limX, freeY = std::abs(t.y * invZ) < limY; // clamped: constant
    const Vec3d r2(view.rotation.m[2][0], view.rotation.m[2][1], view.rotation.m[2][2]);
    const double a0 = -view.fx * invZ * dot(dJw0, r2), a1 = -view.fy * invZ * dot(dJw1, r2);
    Vec3d d;
    d.x = g.d[kU] * view.fx * invZ + (freeX ? a0 * invZ : 0.0);
    d.y = g.d[kV] * view.fy * invZ + (freeY ? a1 * invZ : 0.0);
    d.z = -g.d[kU] * view.fx * t.x * invZ * invZ - g.d[kV] * view.fy * t.y * invZ * invZ - invZ * (dot(dJw0, jw0) + dot(dJw1, jw1)) +
          (freeX ? a0 * -t.x * invZ * invZ : 0.0) + (freeY ? a1 * -t.y * invZ * invZ : 0.0);
    return d;
}

/// Chain one Gaussian's screen gradients back to its parameters (projectSplat() and splatColour()).
void splatBackward(const GaussianCloud& cloud, std::size_t i, const PinholeView& view, const SplatGrad& g, CloudGradients& out)
{
    const Vec3d mean(cloud.mean(i));
    const Mat3d rv = Mat3d::from(view.rotation);
    const Vec3d t = rv * mean + Vec3d(view.translation);
    const double limX = kSplatFrustumSlack * 0.5 * view.width / view.fx, limY = kSplatFrustumSlack * 0.5 * view.height / view.fy;
    const double txz = std::clamp(t.x / t.z, -limX, limX), tyz = std::clamp(t.y / t.z, -limY, limY);
    Vec3d jw0, jw1;
    for (int c = 0; c < 3; ++c) {
        jw0[c] = view.fx / t.z * (rv.m[0][c] - txz * rv.m[2][c]);
        jw1[c] = view.fy / t.z * (rv.m[1][c] - tyz * rv.m[2][c]);
    }
    const Vec3d scale(cloud.scale(i));
    const Mat3d rq = quatToMatrix(Quat<double>{cloud.rotation(i).w, cloud.rotation(i).x, cloud.rotation(i).y, cloud.rotation(i).z});
    Mat3d m; // R S
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) m.m[r][c] = rq.m[r][c] * scale[c];
    const Mat3d cov = m * m.transposed();
    const Vec3d s0 = cov * jw0, s1 = cov * jw1;
    const double a = dot(jw0, s0) + kSplatDilation, b = dot(jw0, s1), c = dot(jw1, s1) + kSplatDilation;
    const double det = a * c - b * b, d2 = det * det;
    // conic = (c, -b, a) / det
    const double da = g.d[kConicA] * (-c * c / d2) + g.d[kConicB] * (b * c / d2) + g.d[kConicC] * (-b * b / d2);
    const double db = g.d[kConicA] * (2 * b * c / d2) + g.d[kConicB] * (-(det + 2 * b * b) / d2) + g.d[kConicC] * (2 * a * b / d2);
    const double dc = g.d[kConicA] * (-b * b / d2) + g.d[kConicB] * (a * b / d2) + g.d[kConicC] * (-a * a / d2);
    const Vec3d dJw0 = s0 * (2 * da) + s1 * db, dJw1 = s1 * (2 * dc) + s0 * db;
    const Vec3d dMean = rv.transposed() * cameraMeanGrad(view, t, g, dJw0, dJw1, jw0, jw1);
    // dL/dCov = da jw0 jw0^T + db jw0 jw1^T + dc jw1 jw1^T; Cov = M M^T -> dL/dM = (G + G^T) M.
    Mat3d gs;
    for (int r = 0; r < 3; ++r)
        for (int k = 0; k < 3; ++k)
            gs.m[r][k] = 2 * da * jw0[r] * jw0[k] + db * (jw0[r] * jw1[k] + jw1[r] * jw0[k]) + 2 * dc * jw1[r] * jw1[k];
    const Mat3d dM = gs * m;
    Mat3d dRq;
    for (int r = 0; r < 3; ++r)
        for (int k = 0; k < 3; ++k) dRq.m[r][k] = dM.m[r][k] * scale[k];
    for (int k = 0; k < 3; ++k) {
        double ds = 0;
        for (int r = 0; r < 3; ++r) ds += dM.m[r][k] * rq.m[r][k];
        out.logScales[3 * i + std::size_t(k)] += float(ds * scale[k]);
        out.means[3 * i + std::size_t(k)] += float(dMean[k]);
    }
    const std::array<double, 4> dq = quatMatrixGrad(cloud.rotation(i), dRq);
    for (int k = 0; k < 4; ++k) out.rotations[4 * i + std::size_t(k)] += float(dq[std::size_t(k)]);
    const double alpha = cloud.alpha(i);
    out.opacities[i] += float(g.d[kOpacity] * alpha * (1 - alpha));
    // Colour = max(0, 0.5 + sum_k Y_k h_k): no gradient where the clamp holds.
    const Vec3f dir = cloud.mean(i) - view.centre;
    const float n = std::sqrt(dot(dir, dir));
    float basis[16];
    evalShBasis(cloud.shDegree, n > 0 ? dir / n : Vec3f(0, 0, 0), basis);
    const Vec3f sum = evalShSum<float>(cloud.shDegree, cloud.shOf(i), dir);
    float* dsh = out.sh.data() + i * std::size_t(cloud.shStride());
    for (int ch = 0; ch < 3; ++ch) {
        if (!(sum[ch] + 0.5f > 0.0f)) continue;
        for (int k = 0; k < cloud.shCoeffs(); ++k) dsh[3 * k + ch] += float(basis[k] * g.d[kColour + ch]);
    }
    out.screenNorm[i] += float(std::hypot(g.d[kU] * 0.5 * view.width, g.d[kV] * 0.5 * view.height));
    out.visible[i] += 1;
}

} // namespace

void renderBackward(const GaussianCloud& cloud, const RenderTape& tape, const std::vector<float>& dImage,
                    CloudGradients& grads, bool threaded)
{
    const int w = tape.image.width, h = tape.image.height;
    if (dImage.size() != std::size_t(w) * std::size_t(h) * 3)
        throw InputError(msg("renderBackward: dImage has ", dImage.size(), " values for a ", w, "x", h, " image"));
    if (grads.opacities.size() != cloud.size()) throw InputError("renderBackward: gradients not sized for the model");
    std::vector<EntryGrad> entries(tape.bins.keys.size());
    parallelForRange(tape.bins.tiles(), 1, threaded,
                     TileBackwardOp{tape.bins, tape.state, dImage, tape.background, w, h, entries});
    // Entry order (tile-major) is fixed, so these sums do not depend on the thread count.
    std::vector<SplatGrad> splat(cloud.size());
    for (std::size_t e = 0; e < entries.size(); ++e) {
        SplatGrad& s = splat[std::uint32_t(tape.bins.keys[e])];
        for (int k = 0; k < kSlots; ++k) s.d[k] += entries[e].d[k];
        s.any = true;
    }
    parallelFor(cloud.size(), 256, threaded, [&](std::size_t i) {
        if (splat[i].any) splatBackward(cloud, i, tape.view, splat[i], grads);
    });
}

void CloudGradients::reset(const GaussianCloud& cloud)
{
    const std::size_t n = cloud.size();
    means.assign(3 * n, 0.0f);
    logScales.assign(3 * n, 0.0f);
    rotations.assign(4 * n, 0.0f);
    opacities.assign(n, 0.0f);
    sh.assign(n * std::size_t(cloud.shStride()), 0.0f);
    screenNorm.assign(n, 0.0f);
    visible.assign(n, 0);
}

RenderTape renderForTraining(const GaussianCloud& cloud, const Camera& camera, const RenderOptions& options)
{
    checkRenderInputs(cloud, camera);
    RenderTape tape;
    tape.view = pinholeView(camera);
    tape.background = options.background;
    tape.bins = detail::binSplats(cloud, tape.view, options.threaded);
    tape.image = Image(camera.width, camera.height, 4);
    detail::compositeTiles(tape.bins, options.background, options.threaded, tape.image, &tape.state);
    return tape;
}

} // namespace splatwarp
