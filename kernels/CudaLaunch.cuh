#pragma once
/// @file CudaLaunch.cuh
/// @brief What every kernel file needs: one thread per element launches (checked, no device
///        synchronisation), the element index, CUB calls with a growing temporary buffer, and an
///        owned non-blocking stream.
#include <cuda_runtime.h>

#include <algorithm>
#include <cstddef>

#include "kernels/CudaCheck.h"
#include "kernels/DeviceBuffer.h"

namespace splatwarp::cuda {

/// Threads per block of the per-element kernels: 8 warps, full occupancy on sm_75..sm_90.
constexpr int kBlock = 256;

/// Index of this thread in a 1-D launch.
__device__ __forceinline__ std::size_t globalIndex() { return std::size_t(blockIdx.x) * blockDim.x + threadIdx.x; }

/// Blocks of `block` threads covering n elements.
inline unsigned blocksFor(std::size_t n, int block = kBlock) { return unsigned((n + std::size_t(block) - 1) / std::size_t(block)); }

/// Launch `kernel` over n threads in blocks of Block (skipped when n == 0) and check the launch
/// (asynchronous faults surface at the next checked synchronising call).
template <int Block = kBlock, typename Kernel, typename... Args>
void launch(const char* name, Kernel kernel, std::size_t n, cudaStream_t stream, Args... args)
{
    if (n == 0) return;
    kernel<<<blocksFor(n, Block), Block, 0, stream>>>(args...);
    checkCuda(cudaGetLastError(), name, __FILE__, __LINE__);
}

/// Row pitch (floats) of a shared-memory tile of Width-float rows: odd, so the rows of a warp's
/// 32 threads start in 32 different banks (pitch 48 would put 16 threads on each of 2 banks).
template <int Width>
constexpr int tilePitch()
{
    return Width % 2 == 0 ? Width + 1 : Width;
}

/// Copy `rows` rows of a row-major [rows, Width] global array into a shared tile (pitch
/// tilePitch<Width>()), coalesced: the block's threads read consecutive floats. Every thread of
/// the block calls it; __syncthreads() before reading the tile.
template <int Width>
__device__ void loadTileRows(const float* src, int rows, float* tile)
{
    for (int i = int(threadIdx.x); i < rows * Width; i += int(blockDim.x))
        tile[(i / Width) * tilePitch<Width>() + i % Width] = src[i];
}

/// The reverse of loadTileRows: `rows` tile rows to a row-major global array, coalesced.
template <int Width>
__device__ void storeTileRows(const float* tile, int rows, float* dst)
{
    for (int i = int(threadIdx.x); i < rows * Width; i += int(blockDim.x))
        dst[i] = tile[(i / Width) * tilePitch<Width>() + i % Width];
}

/// Run a CUB device algorithm (size query, then run) with a temporary buffer that grows.
template <typename F>
void cubCall(DeviceBuffer<unsigned char>& temp, const F& f)
{
    std::size_t bytes = 0;
    SPLATWARP_CUDA_CHECK(f(nullptr, bytes));
    temp.resize(std::max<std::size_t>(bytes, 1));
    SPLATWARP_CUDA_CHECK(f(temp.data(), bytes));
}

/// An owned non-blocking stream (work on it never waits for the legacy default stream).
struct StreamHolder {
    cudaStream_t stream = nullptr;
    StreamHolder() { SPLATWARP_CUDA_CHECK(cudaStreamCreateWithFlags(&stream, cudaStreamNonBlocking)); }
    ~StreamHolder() { cudaStreamDestroy(stream); }
    StreamHolder(const StreamHolder&) = delete;
    StreamHolder& operator=(const StreamHolder&) = delete;
};

} // namespace splatwarp::cuda
