#pragma once
/// @file CellTargetMath.h
/// @brief Per-element functions of the rest-target evaluation through the cell index grid, in
///        the GPU data layout (plain pointers): the CUDA kernels (kernels/FeaturesCuda.cu) are thin
///        wrappers around them, the CPU feature loop shares accumulateFeatures(), and CPU tests
///        run them over host arrays. Steps: each Gaussian emits a (cell, Gaussian) pair for every
///        active cell its pruning box overlaps; pairs are stably sorted by cell (Gaussians stay
///        ascending within a cell); each cell's pair range is marked; each sample sums its cell's
///        Gaussians in ascending order -- the contributing set and order of the CPU path.
#include <cmath>
#include <cstddef>
#include <cstdint>

#include <nanovdb/NanoVDB.h>

#include "core/HostDevice.h"
#include "field/CellIndexGrid.h"
#include "field/PreparedGaussian.h"

namespace splatwarp {

/// The NanoVDB type of the cell index grid.
using NanoCellGrid = nanovdb::NanoGrid<std::int32_t>;

/// @brief The grid inside a CellIndexGrid buffer (host or device copy of the same bytes), or
///        null when the bytes are not a NanoVDB Int32 grid.
SPLATWARP_HOST_DEVICE const NanoCellGrid* asNanoCellGrid(const void* bytes)
{
    const NanoCellGrid* g = reinterpret_cast<const NanoCellGrid*>(bytes);
    return g && g->isValid() && g->gridType() == nanovdb::GridType::Int32 ? g : nullptr;
}

/// @brief Host view of a CellIndexGrid (null when empty or not an Int32 NanoVDB grid).
inline const NanoCellGrid* nanoCellGrid(const CellIndexGrid& grid)
{
    return grid.empty() ? nullptr : asNanoCellGrid(grid.data());
}

/// @brief Inclusive integer cell range of a prepared Gaussian's pruning box (floor(x / h) of its
///        corners, in double as vdb/SampleGrid's topology). False for a Gaussian that never
///        contributes (it emits no pairs).
SPLATWARP_HOST_DEVICE bool gaussianCellRange(const PreparedGaussian& g, double cellSize, int lo[3], int hi[3])
{
    if (!(g.radius2 >= 0.0f)) return false;
    for (int k = 0; k < 3; ++k) {
        const double c = double(g.mean[k]), half = double(g.halfExtent[k]);
        lo[k] = int(std::floor((c - half) / cellSize));
        hi[k] = int(std::floor((c + half) / cellSize));
    }
    return true;
}

/// @brief The (cell, Gaussian) pairs of Gaussian `index`: every active cell of its cell range,
///        in x, y, z loop order. With null outputs only counts; else writes count entries to
///        cells[] and gaussians[] (the caller's offset for this Gaussian already applied).
/// @return the number of pairs
SPLATWARP_HOST_DEVICE std::uint32_t gaussianCellPairs(std::uint32_t index, const PreparedGaussian& g, double cellSize,
                                                      const NanoCellGrid& grid, std::uint32_t* cells,
                                                      std::uint32_t* gaussians)
{
    int lo[3], hi[3];
    if (!gaussianCellRange(g, cellSize, lo, hi)) return 0;
    auto acc = grid.getAccessor(); // caches the last node: neighbouring cells share leaves
    std::uint32_t count = 0;
    for (int x = lo[0]; x <= hi[0]; ++x)
        for (int y = lo[1]; y <= hi[1]; ++y)
            for (int z = lo[2]; z <= hi[2]; ++z) {
                const std::int32_t c = acc.getValue(nanovdb::Coord(x, y, z));
                if (c < 0) continue; // outside the topology (cannot happen for boxes it was built from)
                if (cells) {
                    cells[count] = std::uint32_t(c);
                    gaussians[count] = index;
                }
                ++count;
            }
    return count;
}

/// @brief Mark the pair range [cellStart[c], cellEnd[c]) of the cell of sorted pair p (cells
///        without pairs keep the caller's zero-initialised empty range).
SPLATWARP_HOST_DEVICE void markCellRange(std::size_t p, const std::uint32_t* sortedCells, std::size_t pairs,
                                         std::uint32_t* cellStart, std::uint32_t* cellEnd)
{
    const std::uint32_t c = sortedCells[p];
    if (p == 0 || sortedCells[p - 1] != c) cellStart[c] = std::uint32_t(p);
    if (p + 1 == pairs || sortedCells[p + 1] != c) cellEnd[c] = std::uint32_t(p + 1);
}

/// @brief F and O at x from candidate Gaussians cand[0..count) in the given order (the CPU
///        path's inner loop too): F = sum w H, O = sum w with w = alpha*G where it reaches the
///        cutoff. f (shStride floats, may be null) is overwritten.
/// @return the number of contributing pairs
template <typename Index>
SPLATWARP_HOST_DEVICE std::uint32_t accumulateFeatures(const Vec3f& x, const Index* cand, std::size_t count,
                                                       const PreparedGaussian* gaussians, const float* sh,
                                                       int shStride, float cutoff, float* f, float& o)
{
    if (f)
        for (int s = 0; s < shStride; ++s) f[s] = 0.0f;
    o = 0.0f;
    std::uint32_t contributing = 0;
    for (std::size_t k = 0; k < count; ++k) {
        const std::size_t i = std::size_t(cand[k]);
        const PreparedGaussian& g = gaussians[i];
        const float w = g.weight(x - g.mean, cutoff);
        if (w == 0.0f) continue;
        ++contributing;
        o += w;
        if (f) {
            const float* h = sh + i * std::size_t(shStride);
            for (int s = 0; s < shStride; ++s) f[s] += w * h[s];
        }
    }
    return contributing;
}

/// @brief Plain-pointer view of the sorted cell lists and the samples (device or host arrays).
struct CellTargetView {
    const PreparedGaussian* gaussians = nullptr; ///< [N]
    const float* sh = nullptr;                   ///< [N, shStride]
    int shStride = 0;
    float cutoff = 0.0f;
    const float* positions = nullptr;            ///< [M,3] rest sample positions
    const std::int32_t* sampleCell = nullptr;    ///< [M] cell of each sample
    const std::uint32_t* cellStart = nullptr;    ///< [C] first sorted pair of each cell
    const std::uint32_t* cellEnd = nullptr;      ///< [C] one past its last
    const std::uint32_t* cellGaussians = nullptr; ///< [P] Gaussian of each sorted pair
};

/// @brief The candidates sample s tests: the length of its cell's Gaussian list (pairsTested
///        is their sum over the samples, whatever each cell's sample count).
SPLATWARP_HOST_DEVICE std::uint32_t cellSampleCandidates(std::size_t s, const CellTargetView& v)
{
    const std::size_t c = std::size_t(v.sampleCell[s]);
    return v.cellEnd[c] - v.cellStart[c];
}

/// @brief Targets of sample s from its cell's Gaussian list: its features f (v.shStride floats,
///        may be null; a row of the [M, shStride] output or a scratch array) and opacity o.
/// @return the number of contributing pairs
SPLATWARP_HOST_DEVICE std::uint32_t evaluateCellSample(std::size_t s, const CellTargetView& v, float* f, float& o)
{
    const std::size_t c = std::size_t(v.sampleCell[s]);
    const std::uint32_t begin = v.cellStart[c], end = v.cellEnd[c];
    const Vec3f x(v.positions[3 * s], v.positions[3 * s + 1], v.positions[3 * s + 2]);
    return accumulateFeatures(x, v.cellGaussians + begin, std::size_t(end - begin), v.gaussians, v.sh, v.shStride,
                              v.cutoff, f, o);
}

} // namespace splatwarp
