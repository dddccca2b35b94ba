#pragma once
/// @file BoxBinsCuda.cuh
/// @brief The GPU side of field/GaussianBins: axis-aligned boxes listed in every cell of a
///        uniform grid they overlap, as (64-bit cell key, box) entries that CUB sorts by key; a
///        point finds its candidate boxes by binary search of its own cell's key.
#include <cuda_runtime.h>

#include <cub/cub.cuh>

#include <algorithm>
#include <cstddef>
#include <cstdint>

#include "kernels/CudaCheck.h"
#include "kernels/CudaLaunch.cuh"
#include "kernels/DeviceBuffer.h"
#include "core/Error.h"

namespace splatwarp::cuda {
namespace {

// 21 bits per axis packed into a 64-bit cell key (as field/GaussianBins.cpp): coordinates are
// clamped into range, which only merges far cells (a lookup stays a superset).
constexpr long long kAxisBias = 1ll << 20;
constexpr long long kAxisMax = (1ll << 21) - 1;
__device__ __forceinline__ long long binCoord(float v, float inv)
{
    const double c = floor(double(v) * inv) + double(kAxisBias);
    return (long long)(fmin(fmax(c, 0.0), double(kAxisMax)));
}

__device__ __forceinline__ unsigned long long packKey(long long x, long long y, long long z)
{
    return ((unsigned long long)x << 42) | ((unsigned long long)y << 21) | (unsigned long long)z;
}

/// Empty (hi < lo) or not finite: left out of the bins, so one NaN/Inf box can neither make the
/// mean edge (and so the cell size) infinite nor span every cell.
__device__ __forceinline__ bool emptyBox(const float* lo, const float* hi) // [3] each
{
    for (int a = 0; a < 3; ++a)
        if (!isfinite(lo[a]) || !isfinite(hi[a])) return true;
    return !(hi[0] >= lo[0] && hi[1] >= lo[1] && hi[2] >= lo[2]);
}

/// Per-box bin count cap: 2^21 cells per axis could give 2^63 for one box, and the scan of many
/// would wrap; capped, any total stays far below 2^64 and the 32-bit entry check reports it.
constexpr unsigned long long kMaxBinsPerBox = 1ull << 40;

/// First index in [0, n) with keys[index] >= key (n if none).
template <typename K>
__device__ std::size_t lowerBound(const K* keys, std::size_t n, K key)
{
    std::size_t lo = 0, hi = n;
    while (lo < hi) {
        const std::size_t mid = (lo + hi) / 2;
        if (keys[mid] < key) lo = mid + 1;
        else hi = mid;
    }
    return lo;
}

__device__ __forceinline__ bool insideBox(const float* lo, const float* hi, std::uint32_t k, const float* p)
{
    return p[0] >= lo[3 * k] && p[0] <= hi[3 * k] && p[1] >= lo[3 * k + 1] && p[1] <= hi[3 * k + 1] &&
           p[2] >= lo[3 * k + 2] && p[2] <= hi[3 * k + 2];
}

/// Bin cells spanned by each box (0 for empty boxes).
__global__ void binCountKernel(std::size_t g, const float* lo, const float* hi, float inv,
                               unsigned long long* count /* [G+1]; count[G] = 0 for the exclusive scan */)
{
    const std::size_t k = globalIndex();
    if (k > g) return;
    unsigned long long c = 0;
    if (k < g && !emptyBox(lo + 3 * k, hi + 3 * k)) {
        c = 1;
        for (int a = 0; a < 3; ++a) c *= (unsigned long long)(binCoord(hi[3 * k + a], inv) - binCoord(lo[3 * k + a], inv) + 1);
        c = c < kMaxBinsPerBox ? c : kMaxBinsPerBox;
    }
    count[k] = c;
}

/// (cell key, box) entries of each box at its scanned offset, boxes in ascending order.
__global__ void binFillKernel(std::size_t g, const float* lo, const float* hi, float inv,
                              const unsigned long long* start /* [G+1] */, unsigned long long* keys /* [E] */,
                              std::uint32_t* boxes /* [E] */)
{
    const std::size_t k = globalIndex();
    if (k >= g || start[k + 1] == start[k]) return;
    long long a[3], b[3];
    for (int i = 0; i < 3; ++i) {
        a[i] = binCoord(lo[3 * k + i], inv);
        b[i] = binCoord(hi[3 * k + i], inv);
    }
    unsigned long long e = start[k];
    for (long long x = a[0]; x <= b[0]; ++x)
        for (long long y = a[1]; y <= b[1]; ++y)
            for (long long z = a[2]; z <= b[2]; ++z) {
                keys[e] = packKey(x, y, z);
                boxes[e] = std::uint32_t(k);
                ++e;
            }
}

struct EdgeSum {
    double edge = 0;          ///< sum of the largest box edges
    unsigned long long n = 0; ///< non-empty boxes
};
struct EdgeSumOp {
    __host__ __device__ EdgeSum operator()(const EdgeSum& a, const EdgeSum& b) const { return {a.edge + b.edge, a.n + b.n}; }
};

__global__ void edgeKernel(std::size_t g, const float* lo /* [G,3] */, const float* hi /* [G,3] */, EdgeSum* out /* [G] */)
{
    const std::size_t k = globalIndex();
    if (k >= g) return;
    const float* a = lo + 3 * k;
    const float* b = hi + 3 * k;
    EdgeSum e;
    if (!emptyBox(a, b)) {
        e.edge = double(fmaxf(b[0] - a[0], fmaxf(b[1] - a[1], b[2] - a[2])));
        e.n = 1;
    }
    out[k] = e;
}

/// @brief Device boxes binned into a uniform grid: (cell key, box) entries sorted by key, boxes
///        ascending within a cell (stable sort of entries filled in box order). Buffers settle at
///        their largest size over rebuilds. Used by Stage II's coverage and the feature evaluator.
class BoxBins {
public:
    /// Bin entries allowed per box before the cell doubles: the per-sample reference coverage
    /// (tests/cuda/SampleCoverage.h) bins at half GaussianBins::suggestCellSize (<= 32 entries
    /// per box), so up to 8x that.
    static constexpr double kMaxEntriesPerBox = 256.0;

    /// @brief Bin g boxes lo, hi [G,3] (device; empty boxes, lo > hi, are left out). Cell edge:
    ///        half the mean box edge, doubled while the entries would exceed kMaxEntriesPerBox
    ///        per box. Reads back two counts. `who` names the caller in errors.
    /// @return false when no box is non-empty (no entries)
    bool build(std::size_t g, const float* lo, const float* hi, cudaStream_t st, const char* who)
    {
        mEntries = 0;
        if (g == 0) return false;
        mEdges.resize(g);
        launch("edgeKernel", edgeKernel, g, st, g, lo, hi, mEdges.data());
        mEdgeTotal.resize(1);
        cubCall(mTemp, [&](void* t, std::size_t& b) {
            return cub::DeviceReduce::Reduce(t, b, mEdges.data(), mEdgeTotal.data(), g, EdgeSumOp(), EdgeSum(), st);
        });
        EdgeSum edges;
        mEdgeTotal.download(&edges, 1, st);
        if (edges.n == 0) return false;
        double cell = std::max(0.5 * edges.edge / double(edges.n), 1e-12);
        unsigned long long entries = 0;
        mStart.resize(g + 1);
        for (int round = 0;; ++round) {
            mInv = 1.0f / float(cell);
            launch("binCountKernel", binCountKernel, g + 1, st, g, lo, hi, mInv, mStart.data());
            cubCall(mTemp, [&](void* t, std::size_t& b) {
                return cub::DeviceScan::ExclusiveSum(t, b, mStart.data(), mStart.data(), g + 1, st);
            });
            SPLATWARP_CUDA_CHECK(cudaMemcpyAsync(&entries, mStart.data() + g, sizeof(entries), cudaMemcpyDeviceToHost, st));
            SPLATWARP_CUDA_CHECK(cudaStreamSynchronize(st));
            if (double(entries) <= kMaxEntriesPerBox * double(edges.n) || round >= 64) break;
            cell *= 2;
        }
        if (entries > 0xffffffffull)
            throw DeviceLimitError(msg(who, ": bins would hold ", entries, " entries; too many for 32-bit indices"));
        mInv = 1.0f / float(cell);
        mKeys.resize(entries);
        mKeysSorted.resize(entries);
        mBoxes.resize(entries);
        mBoxesSorted.resize(entries);
        launch("binFillKernel", binFillKernel, g, st, g, lo, hi, mInv, (const unsigned long long*)mStart.data(),
               mKeys.data(), mBoxes.data());
        // Stable LSD radix sort: within a cell the boxes stay ascending (filled in box order).
        cubCall(mTemp, [&](void* t, std::size_t& b) {
            return cub::DeviceRadixSort::SortPairs(t, b, (const unsigned long long*)mKeys.data(), mKeysSorted.data(),
                                                   (const std::uint32_t*)mBoxes.data(), mBoxesSorted.data(), entries, 0,
                                                   63, st);
        });
        mEntries = entries;
        return true;
    }

    float inv() const { return mInv; }                 ///< 1 / cell edge of the last build
    std::size_t entries() const { return mEntries; }  ///< E (0 after a build that returned false)
    const unsigned long long* keys() const { return mKeysSorted.data(); }  ///< [E] sorted cell keys
    const std::uint32_t* boxes() const { return mBoxesSorted.data(); }     ///< [E] box of each entry

private:
    DeviceBuffer<EdgeSum> mEdges{"box edges"}, mEdgeTotal{"box edge sum"};
    DeviceBuffer<unsigned long long> mStart{"bin entry offsets"}, mKeys{"bin keys"}, mKeysSorted{"sorted bin keys"};
    DeviceBuffer<std::uint32_t> mBoxes{"bin boxes"}, mBoxesSorted{"sorted bin boxes"};
    DeviceBuffer<unsigned char> mTemp{"CUB temporary storage"};
    float mInv = 0.0f;
    std::size_t mEntries = 0;
};

} // namespace
} // namespace splatwarp::cuda
