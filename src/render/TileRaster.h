#pragma once
/// @file TileRaster.h
/// @brief The tiled forward pass of the CPU splat rasteriser, shared by renderGaussians() and its
///        differentiable version (render/RasterizerBackward.h): projection, tile binning with a
///        total (depth, index) order, front-to-back compositing. Internal to src/render.
#include <cstdint>
#include <vector>

#include "core/GaussianCloud.h"
#include "image/Image.h"
#include "render/SplatProjection.h"

namespace splatwarp::detail {

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

/// Splats binned by screen tile: tile t's splats, front to back, are keys[tileStart[t] .. tileStart[t+1]).
struct TileBins {
    std::vector<ScreenSplat> splats; ///< [N] one per Gaussian
    std::vector<TileKey> keys;       ///< low 32 bits: splat index
    std::vector<std::size_t> tileStart;
    int tilesX = 0, tilesY = 0;
    std::size_t tiles() const { return tileStart.empty() ? 0 : tileStart.size() - 1; }
};

/// @brief Project every Gaussian and bin the visible ones by tile.
TileBins binSplats(const GaussianCloud& cloud, const PinholeView& view, bool threaded);

/// @brief What the backward pass needs per pixel: the final transmittance and the entry (index
///        into keys) at which compositing stopped (the tile's end when it never did).
struct PixelState {
    std::vector<float> transmittance;  ///< [H*W]
    std::vector<std::size_t> stopEntry; ///< [H*W]
};

/// @brief Composite every tile into `image` (RGBA); fills `state` when it is not null.
void compositeTiles(const TileBins& bins, const Vec3f& background, bool threaded, Image& image, PixelState* state);

} // namespace splatwarp::detail
