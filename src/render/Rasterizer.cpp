#include "render/Rasterizer.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <vector>

#include "core/Error.h"
#include "core/ParallelFor.h"
#include "field/GaussianMath.h"

namespace splatwarp {

namespace {

/// Sort key of a splat within a tile: depth bits (positive floats order like their bits) above the
/// splat index. Sorting these orders each tile front to back with ties broken by index, a total
/// order, so the result depends neither on the sort nor on the order the entries were filled.
using TileKey = std::uint64_t;

/// A splat prepared for compositing.
struct ScreenSplat {
    ProjectedSplat p;
    Vec3f colour;
    PixelBox range; ///< 3-sigma pixel range (assigns tiles); empty when the splat covers no pixel
    PixelBox reach; ///< pixels where alpha can reach the cutoff
};

/// Project Gaussians [begin, end): screen footprint, colour and pixel range.
struct ProjectOp {
    const GaussianCloud& cloud;
    const PinholeView& view;
    std::vector<ScreenSplat>& out;
    void operator()(std::size_t begin, std::size_t end) const
    {
        for (std::size_t i = begin; i < end; ++i) {
            ScreenSplat& s = out[i];
            const Vec3f mean = cloud.mean(i);
            const Mat3f cov = gaussianCovariance(cloud.rotation(i), cloud.scale(i));
            // Splats that never reach the alpha cutoff get no tiles at all.
            if (!projectSplatOnScreen(view, mean, cov, cloud.alpha(i), s.p, s.range, s.reach)) continue;
            s.colour = splatColour(view, cloud.shDegree, cloud.shOf(i), mean);
        }
    }
};

/// Composite one tile front to back, splat by splat over the pixels each one can reach; every
/// pixel still sees its splats in (depth, index) order, so this equals a per-pixel loop.
struct CompositeOp {
    const std::vector<ScreenSplat>& splats;
    const std::vector<TileKey>& keys;
    const std::vector<std::size_t>& tileStart;
    int tilesX;
    Vec3f background;
    Image& image;
    void operator()(std::size_t beginTile, std::size_t endTile) const
    {
        constexpr int kPixels = kSplatTileSize * kSplatTileSize;
        float transmittance[kPixels];
        Vec3f colour[kPixels];
        bool done[kPixels];
        for (std::size_t tile = beginTile; tile < endTile; ++tile) {
            const int tx0 = int(tile % std::size_t(tilesX)) * kSplatTileSize;
            const int ty0 = int(tile / std::size_t(tilesX)) * kSplatTileSize;
            const int tx1 = std::min(image.width, tx0 + kSplatTileSize) - 1;
            const int ty1 = std::min(image.height, ty0 + kSplatTileSize) - 1;
            int active = (tx1 - tx0 + 1) * (ty1 - ty0 + 1);
            for (int k = 0; k < kPixels; ++k) {
                transmittance[k] = 1.0f;
                colour[k] = Vec3f(0.0f, 0.0f, 0.0f);
                done[k] = false;
            }
            for (std::size_t e = tileStart[tile]; e < tileStart[tile + 1] && active > 0; ++e) {
                const ScreenSplat& s = splats[std::uint32_t(keys[e])]; // low 32 bits: splat index
                const int x0 = std::max(tx0, s.reach.x0), x1 = std::min(tx1, s.reach.x1);
                const int y0 = std::max(ty0, s.reach.y0), y1 = std::min(ty1, s.reach.y1);
                for (int y = y0; y <= y1; ++y)
                    for (int x = x0; x <= x1; ++x) {
                        const int k = (y - ty0) * kSplatTileSize + (x - tx0);
                        if (done[k]) continue;
                        const float alpha = splatAlpha(s.p, float(x) + 0.5f, float(y) + 0.5f);
                        if (alpha == 0.0f) continue;
                        const float next = transmittance[k] * (1.0f - alpha);
                        // As 3DGS: stop before the splat that would make the pixel (almost) opaque.
                        if (next < kSplatMinTransmittance) {
                            done[k] = true;
                            --active;
                            continue;
                        }
                        colour[k] += s.colour * (alpha * transmittance[k]);
                        transmittance[k] = next;
                    }
            }
            for (int y = ty0; y <= ty1; ++y)
                for (int x = tx0; x <= tx1; ++x) {
                    const int k = (y - ty0) * kSplatTileSize + (x - tx0);
                    for (int c = 0; c < 3; ++c) image.at(x, y, c) = colour[k][c] + transmittance[k] * background[c];
                    image.at(x, y, 3) = 1.0f - transmittance[k];
                }
        }
    }
};

} // namespace

void checkRenderInputs(const GaussianCloud& cloud, const Camera& camera)
{
    cloud.checkConsistent();
    if (camera.width <= 0 || camera.height <= 0 || !(camera.fx > 0) || !(camera.fy > 0))
        throw InputError(msg("camera '", camera.name, "' needs a positive image size and focal length"));
}

Image renderGaussians(const GaussianCloud& cloud, const Camera& camera, const RenderOptions& options)
{
    checkRenderInputs(cloud, camera);
    const PinholeView view = pinholeView(camera);
    const std::size_t n = cloud.size();
    const bool threaded = options.threaded;

    std::vector<ScreenSplat> splats(n);
    parallelForRange(n, 1024, threaded, ProjectOp{cloud, view, splats});

    // Bucket the splats by tile (counting pass, prefix sum, fill), then sort every tile's bucket.
    const int tilesX = (view.width + kSplatTileSize - 1) / kSplatTileSize;
    const int tilesY = (view.height + kSplatTileSize - 1) / kSplatTileSize;
    const std::size_t tiles = std::size_t(tilesX) * std::size_t(tilesY);
    const auto forEachTile = [&](const ScreenSplat& s, const auto& f) {
        const PixelBox& r = s.range;
        if (r.x1 < r.x0) return;
        for (int ty = r.y0 / kSplatTileSize; ty <= r.y1 / kSplatTileSize; ++ty)
            for (int tx = r.x0 / kSplatTileSize; tx <= r.x1 / kSplatTileSize; ++tx) f(std::size_t(ty) * tilesX + tx);
    };
    std::vector<std::atomic<std::size_t>> cursor(tiles);
    parallelFor(n, 1024, threaded, [&](std::size_t i) {
        forEachTile(splats[i], [&](std::size_t t) { cursor[t].fetch_add(1, std::memory_order_relaxed); });
    });
    std::vector<std::size_t> tileStart(tiles + 1, 0);
    for (std::size_t t = 0; t < tiles; ++t) {
        tileStart[t + 1] = tileStart[t] + cursor[t].load(std::memory_order_relaxed);
        cursor[t].store(tileStart[t], std::memory_order_relaxed);
    }
    std::vector<TileKey> keys(tileStart[tiles]);
    parallelFor(n, 1024, threaded, [&](std::size_t i) {
        std::uint32_t depthBits;
        std::memcpy(&depthBits, &splats[i].p.depth, sizeof(depthBits));
        const TileKey key = (TileKey(depthBits) << 32) | TileKey(i);
        forEachTile(splats[i], [&](std::size_t t) { keys[cursor[t].fetch_add(1, std::memory_order_relaxed)] = key; });
    });
    parallelFor(tiles, 4, threaded, [&](std::size_t t) {
        std::sort(keys.begin() + std::ptrdiff_t(tileStart[t]), keys.begin() + std::ptrdiff_t(tileStart[t + 1]));
    });

    Image image(view.width, view.height, 4);
    parallelForRange(tiles, 1, threaded, CompositeOp{splats, keys, tileStart, tilesX, options.background, image});
    return image;
}

} // namespace splatwarp
