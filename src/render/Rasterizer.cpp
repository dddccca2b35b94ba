#include "render/Rasterizer.h"

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>
#include <vector>

#include "core/Error.h"
#include "field/GaussianKernel.h"

namespace splatwarp {

namespace {

/// One (tile, splat) pair; sorting by (key, splat) orders each tile's splats front to back
/// with ties broken by index, a total order, so the result does not depend on the sort.
struct TileEntry {
    std::uint64_t key; ///< tile << 32 | depth bits (positive floats order like their bits)
    std::uint32_t splat;
    bool operator<(const TileEntry& o) const { return key < o.key || (key == o.key && splat < o.splat); }
};

/// A splat prepared for compositing.
struct ScreenSplat {
    ProjectedSplat p;
    Vec3f colour;
    int x0 = 0, y0 = 0, x1 = -1, y1 = -1; ///< pixel range; empty when x1 < x0
};

template <typename Body>
void forRange(std::size_t n, bool threaded, std::size_t grain, const Body& body)
{
    if (threaded)
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, grain),
                          [&](const tbb::blocked_range<std::size_t>& r) { body(r.begin(), r.end()); });
    else
        body(std::size_t(0), n);
}

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
            if (!projectSplat(view, mean, cov, cloud.alpha(i), s.p)) continue;
            if (!splatPixelRange(s.p, view.width, view.height, s.x0, s.y0, s.x1, s.y1)) {
                s.x1 = s.x0 - 1;
                continue;
            }
            s.colour = splatColour(view, cloud.shDegree, cloud.shOf(i), mean);
        }
    }
};

/// Composite one tile's pixels front to back.
struct CompositeOp {
    const std::vector<ScreenSplat>& splats;
    const std::vector<TileEntry>& entries;
    const std::vector<std::size_t>& tileStart;
    int tilesX;
    Vec3f background;
    Image& image;
    void operator()(std::size_t beginTile, std::size_t endTile) const
    {
        std::vector<const ScreenSplat*> local;
        for (std::size_t tile = beginTile; tile < endTile; ++tile) {
            local.clear();
            for (std::size_t e = tileStart[tile]; e < tileStart[tile + 1]; ++e) local.push_back(&splats[entries[e].splat]);
            const int tx = int(tile % std::size_t(tilesX)), ty = int(tile / std::size_t(tilesX));
            const int xEnd = std::min(image.width, (tx + 1) * kSplatTileSize);
            const int yEnd = std::min(image.height, (ty + 1) * kSplatTileSize);
            for (int y = ty * kSplatTileSize; y < yEnd; ++y)
                for (int x = tx * kSplatTileSize; x < xEnd; ++x) compositePixel(local, x, y);
        }
    }
    void compositePixel(const std::vector<const ScreenSplat*>& list, int x, int y) const
    {
        const float px = float(x) + 0.5f, py = float(y) + 0.5f;
        float transmittance = 1.0f;
        Vec3f colour(0.0f, 0.0f, 0.0f);
        for (const ScreenSplat* s : list) {
            const float alpha = splatAlpha(s->p, px, py);
            if (alpha == 0.0f) continue;
            const float next = transmittance * (1.0f - alpha);
            // As 3DGS: stop before the splat that would make the pixel (almost) fully opaque.
            if (next < kSplatMinTransmittance) break;
            colour += s->colour * (alpha * transmittance);
            transmittance = next;
        }
        for (int c = 0; c < 3; ++c) image.at(x, y, c) = colour[c] + transmittance * background[c];
        image.at(x, y, 3) = 1.0f - transmittance;
    }
};

} // namespace

Image renderGaussians(const GaussianCloud& cloud, const Camera& camera, const RenderOptions& options)
{
    cloud.checkConsistent();
    if (camera.width <= 0 || camera.height <= 0 || !(camera.fx > 0) || !(camera.fy > 0))
        throw InputError(msg("camera '", camera.name, "' needs a positive image size and focal length"));
    const PinholeView view = camera.view();
    const std::size_t n = cloud.size();
    const bool threaded = options.threaded;

    std::vector<ScreenSplat> splats(n);
    forRange(n, threaded, 1024, ProjectOp{cloud, view, splats});

    // Tiles touched per splat, then (tile, depth) entries at prefix-sum offsets.
    const int tilesX = (view.width + kSplatTileSize - 1) / kSplatTileSize;
    const int tilesY = (view.height + kSplatTileSize - 1) / kSplatTileSize;
    std::vector<std::size_t> offset(n + 1, 0);
    for (std::size_t i = 0; i < n; ++i) {
        const ScreenSplat& s = splats[i];
        const std::size_t count = s.x1 < s.x0 ? 0
                                              : std::size_t(s.x1 / kSplatTileSize - s.x0 / kSplatTileSize + 1) *
                                                    std::size_t(s.y1 / kSplatTileSize - s.y0 / kSplatTileSize + 1);
        offset[i + 1] = offset[i] + count;
    }
    std::vector<TileEntry> entries(offset[n]);
    forRange(n, threaded, 1024, [&](std::size_t begin, std::size_t end) {
        for (std::size_t i = begin; i < end; ++i) {
            const ScreenSplat& s = splats[i];
            if (s.x1 < s.x0) continue;
            std::uint32_t depthBits;
            std::memcpy(&depthBits, &s.p.depth, sizeof(depthBits));
            std::size_t e = offset[i];
            for (int ty = s.y0 / kSplatTileSize; ty <= s.y1 / kSplatTileSize; ++ty)
                for (int tx = s.x0 / kSplatTileSize; tx <= s.x1 / kSplatTileSize; ++tx)
                    entries[e++] = {(std::uint64_t(ty * tilesX + tx) << 32) | depthBits, std::uint32_t(i)};
        }
    });
    if (threaded)
        tbb::parallel_sort(entries.begin(), entries.end());
    else
        std::sort(entries.begin(), entries.end());

    const std::size_t tiles = std::size_t(tilesX) * std::size_t(tilesY);
    std::vector<std::size_t> tileStart(tiles + 1, 0);
    for (const TileEntry& e : entries) ++tileStart[(e.key >> 32) + 1];
    for (std::size_t t = 0; t < tiles; ++t) tileStart[t + 1] += tileStart[t];

    Image image(view.width, view.height, 4);
    forRange(tiles, threaded, 1, CompositeOp{splats, entries, tileStart, tilesX, options.background, image});
    return image;
}

} // namespace splatwarp
