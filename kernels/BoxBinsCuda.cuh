#pragma once
/// @file BoxBinsCuda.cuh
/// @brief The GPU side of field/GaussianBins: axis-aligned boxes listed in every cell of a
///        uniform grid they overlap, as (64-bit cell key, box) entries that CUB sorts by key; a
///        point finds its candidate boxes by binary search of its own cell's key.
#include <cuda_runtime.h>

#include <cstddef>
#include <cstdint>

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

__device__ __forceinline__ bool emptyBox(const float* lo, const float* hi) // [3] each
{
    return !(hi[0] >= lo[0] && hi[1] >= lo[1] && hi[2] >= lo[2]);
}

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
    const std::size_t k = std::size_t(blockIdx.x) * blockDim.x + threadIdx.x;
    if (k > g) return;
    unsigned long long c = 0;
    if (k < g && !emptyBox(lo + 3 * k, hi + 3 * k)) {
        c = 1;
        for (int a = 0; a < 3; ++a) c *= (unsigned long long)(binCoord(hi[3 * k + a], inv) - binCoord(lo[3 * k + a], inv) + 1);
    }
    count[k] = c;
}

/// (cell key, box) entries of each box at its scanned offset, boxes in ascending order.
__global__ void binFillKernel(std::size_t g, const float* lo, const float* hi, float inv,
                              const unsigned long long* start /* [G+1] */, unsigned long long* keys /* [E] */,
                              std::uint32_t* boxes /* [E] */)
{
    const std::size_t k = std::size_t(blockIdx.x) * blockDim.x + threadIdx.x;
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

} // namespace
} // namespace splatwarp::cuda
