#include "render/TileRaster.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>

#include "core/ParallelFor.h"
#include "field/GaussianMath.h"

namespace splatwarp::detail {

namespace {

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
    const TileBins& bins;
    Vec3f background;
    Image& image;
    PixelState* state;
    void operator()(std::size_t beginTile, std::size_t endTile) const
    {
        constexpr int kPixels = kSplatTileSize * kSplatTileSize;
        float transmittance[kPixels];
        Vec3f colour[kPixels];
        std::size_t stop[kPixels];
        for (std::size_t tile = beginTile; tile < endTile; ++tile) {
            const int tx0 = int(tile % std::size_t(bins.tilesX)) * kSplatTileSize;
            const int ty0 = int(tile / std::size_t(bins.tilesX)) * kSplatTileSize;
            const int tx1 = std::min(image.width, tx0 + kSplatTileSize) - 1;
            const int ty1 = std::min(image.height, ty0 + kSplatTileSize) - 1;
            int active = (tx1 - tx0 + 1) * (ty1 - ty0 + 1);
            const std::size_t end = bins.tileStart[tile + 1];
            for (int k = 0; k < kPixels; ++k) {
                transmittance[k] = 1.0f;
                colour[k] = Vec3f(0.0f, 0.0f, 0.0f);
                stop[k] = end;
            }
            for (std::size_t e = bins.tileStart[tile]; e < end && active > 0; ++e) {
                const ScreenSplat& s = bins.splats[std::uint32_t(bins.keys[e])]; // low 32 bits: splat index
                const int x0 = std::max(tx0, s.reach.x0), x1 = std::min(tx1, s.reach.x1);
                const int y0 = std::max(ty0, s.reach.y0), y1 = std::min(ty1, s.reach.y1);
                for (int y = y0; y <= y1; ++y)
                    for (int x = x0; x <= x1; ++x) {
                        const int k = (y - ty0) * kSplatTileSize + (x - tx0);
                        if (stop[k] != end) continue;
                        const float alpha = splatAlpha(s.p, float(x) + 0.5f, float(y) + 0.5f);
                        if (alpha == 0.0f) continue;
                        const float next = transmittance[k] * (1.0f - alpha);
                        // As 3DGS: stop before the splat that would make the pixel (almost) opaque.
                        if (next < kSplatMinTransmittance) {
                            stop[k] = e;
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
                    if (!state) continue;
                    const std::size_t p = std::size_t(y) * std::size_t(image.width) + std::size_t(x);
                    state->transmittance[p] = transmittance[k];
                    state->stopEntry[p] = stop[k];
                }
        }
    }
};

} // namespace

TileBins binSplats(const GaussianCloud& cloud, const PinholeView& view, bool threaded)
{
    const std::size_t n = cloud.size();
    TileBins b;
    b.splats.resize(n);
    parallelForRange(n, 1024, threaded, ProjectOp{cloud, view, b.splats});

    // Bucket the splats by tile (counting pass, prefix sum, fill), then sort every tile's bucket.
    b.tilesX = (view.width + kSplatTileSize - 1) / kSplatTileSize;
    b.tilesY = (view.height + kSplatTileSize - 1) / kSplatTileSize;
    const std::size_t tiles = std::size_t(b.tilesX) * std::size_t(b.tilesY);
    const int tilesX = b.tilesX;
    const auto forEachTile = [tilesX](const ScreenSplat& s, const auto& f) {
        const PixelBox& r = s.range;
        if (r.x1 < r.x0) return;
        for (int ty = r.y0 / kSplatTileSize; ty <= r.y1 / kSplatTileSize; ++ty)
            for (int tx = r.x0 / kSplatTileSize; tx <= r.x1 / kSplatTileSize; ++tx) f(std::size_t(ty) * tilesX + tx);
    };
    std::vector<std::atomic<std::size_t>> cursor(tiles);
    parallelFor(n, 1024, threaded, [&](std::size_t i) {
        forEachTile(b.splats[i], [&](std::size_t t) { cursor[t].fetch_add(1, std::memory_order_relaxed); });
    });
    b.tileStart.assign(tiles + 1, 0);
    for (std::size_t t = 0; t < tiles; ++t) {
        b.tileStart[t + 1] = b.tileStart[t] + cursor[t].load(std::memory_order_relaxed);
        cursor[t].store(b.tileStart[t], std::memory_order_relaxed);
    }
    b.keys.resize(b.tileStart[tiles]);
    parallelFor(n, 1024, threaded, [&](std::size_t i) {
        std::uint32_t depthBits;
        std::memcpy(&depthBits, &b.splats[i].p.depth, sizeof(depthBits));
        const TileKey key = (TileKey(depthBits) << 32) | TileKey(i);
        forEachTile(b.splats[i], [&](std::size_t t) { b.keys[cursor[t].fetch_add(1, std::memory_order_relaxed)] = key; });
    });
    parallelFor(tiles, 4, threaded, [&](std::size_t t) {
        std::sort(b.keys.begin() + std::ptrdiff_t(b.tileStart[t]), b.keys.begin() + std::ptrdiff_t(b.tileStart[t + 1]));
    });
    return b;
}

void compositeTiles(const TileBins& bins, const Vec3f& background, bool threaded, Image& image, PixelState* state)
{
    if (state) {
        state->transmittance.assign(std::size_t(image.width) * std::size_t(image.height), 1.0f);
        state->stopEntry.assign(std::size_t(image.width) * std::size_t(image.height), 0);
    }
    parallelForRange(bins.tiles(), 1, threaded, CompositeOp{bins, background, image, state});
}

} // namespace splatwarp::detail
