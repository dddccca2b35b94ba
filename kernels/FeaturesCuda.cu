// Rest sample targets on the GPU: (cell, Gaussian) pairs from NanoVDB lookups, a stable radix
// sort by cell, per-cell ranges, then one thread per sample summing its cell's Gaussians in
// ascending order (the CPU path's contributing set and order). Every kernel is a thin wrapper
// around a function of field/CellTargetKernels.h, which the CPU tests run over host arrays.
#include "FeaturesCuda.h"

#include <cub/cub.cuh>

#include <algorithm>
#include <cstdint>
#include <vector>

#include "CudaCheck.h"
#include "CudaLaunch.cuh"
#include "DeviceBuffer.h"
#include "core/Error.h"
#include "field/CellTargetKernels.h"

namespace splatwarp::cuda {
namespace {

/// Pairs per Gaussian; thread n (one past the last) writes 0 so the exclusive scan's last entry
/// is the total.
__global__ void cellPairCountKernel(std::size_t n, const PreparedGaussian* gaussians, double cellSize,
                                    const NanoCellGrid* grid, unsigned long long* counts)
{
    const std::size_t i = globalIndex();
    if (i > n) return;
    counts[i] = i < n ? gaussianCellPairs(std::uint32_t(i), gaussians[i], cellSize, *grid, nullptr, nullptr) : 0ull;
}

__global__ void cellPairFillKernel(std::size_t n, const PreparedGaussian* gaussians, double cellSize,
                                   const NanoCellGrid* grid, const unsigned long long* offsets, std::uint32_t* cells,
                                   std::uint32_t* owners)
{
    const std::size_t i = globalIndex();
    if (i >= n) return;
    gaussianCellPairs(std::uint32_t(i), gaussians[i], cellSize, *grid, cells + offsets[i],
                      owners + offsets[i]);
}

__global__ void cellRangeKernel(std::size_t pairs, const std::uint32_t* sortedCells, std::uint32_t* cellStart,
                                std::uint32_t* cellEnd)
{
    const std::size_t p = globalIndex();
    if (p >= pairs) return;
    markCellRange(p, sortedCells, pairs, cellStart, cellEnd);
}

/// One thread per sample. Stride is the SH stride as a constant, so the feature loops unroll
/// and the sums stay in registers; each sample's features are written once at the end.
template <int Stride>
__global__ void cellTargetKernel(std::size_t m, CellTargetView view, float* features, float* opacity,
                                 std::uint32_t* contributing)
{
    const std::size_t s = globalIndex();
    if (s >= m) return;
    view.shStride = Stride;
    float f[Stride];
    float o = 0.0f;
    contributing[s] = evaluateCellSample(s, view, f, o);
    for (int k = 0; k < Stride; ++k) features[s * Stride + k] = f[k];
    opacity[s] = o;
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

/// Bits of the largest cell index (at least 1): the radix sort looks at no more.
int keyBits(std::size_t cells)
{
    int bits = 1;
    while (bits < 32 && (std::size_t(1) << bits) < cells) ++bits;
    return bits;
}

template <typename T>
void uploadArray(DeviceBuffer<T>& buffer, const T* host, std::size_t n, cudaStream_t stream)
{
    buffer.resize(n);
    if (n) SPLATWARP_CUDA_CHECK(cudaMemcpyAsync(buffer.data(), host, n * sizeof(T), cudaMemcpyHostToDevice, stream));
}

} // namespace

void evaluateSampleTargetsCuda(const SampleTargetsProblem& p, float* features, float* opacity, FeatureStats* stats)
{
    if (!p.index || !nanoCellGrid(*p.index))
        throw InputError("sample targets (CUDA): the cell index grid is not a NanoVDB Int32 grid");
    if (p.shStride != 3 && p.shStride != 12 && p.shStride != 27 && p.shStride != 48)
        throw InputError(msg("sample targets (CUDA): unsupported SH stride ", p.shStride, " (degree 0..3)"));
    if (!(p.cellSize > 0.0)) throw InputError(msg("sample targets (CUDA): bad cell size ", p.cellSize));
    if (p.samples > 0 && (p.cells == 0 || p.samples % p.cells != 0 || !p.positions || !p.sampleCell))
        throw InputError(msg("sample targets (CUDA): ", p.samples, " samples do not fill ", p.cells, " cells evenly"));
    if (p.gaussianCount > 0 && (!p.gaussians || !p.sh))
        throw InputError("sample targets (CUDA): Gaussians without prepared kernels or SH");
    const std::size_t n = p.gaussianCount, m = p.samples, stride = std::size_t(p.shStride);
    StreamHolder holder;
    const cudaStream_t st = holder.stream;

    // Inputs. The host arrays outlive the stream synchronisation below (downloads synchronise).
    DeviceBuffer<unsigned char> grid("NanoVDB cell index grid");
    uploadArray(grid, static_cast<const unsigned char*>(p.index->data()), p.index->bytes(), st);
    DeviceBuffer<PreparedGaussian> gaussians("prepared Gaussians");
    uploadArray(gaussians, p.gaussians, n, st);
    DeviceBuffer<float> sh("Gaussian SH coefficients");
    uploadArray(sh, p.sh, n * stride, st);
    DeviceBuffer<float> positions("sample positions");
    uploadArray(positions, p.positions, 3 * m, st);
    DeviceBuffer<std::int32_t> sampleCell("sample cells");
    uploadArray(sampleCell, p.sampleCell, m, st);

    // The device copy of the validated host bytes (cudaMalloc aligns far beyond NanoVDB's 32).
    const NanoCellGrid* nano = reinterpret_cast<const NanoCellGrid*>(grid.data());

    // (cell, Gaussian) pairs: count, scan, fill (in Gaussian order).
    DeviceBuffer<unsigned char> temp("CUB temporary storage");
    DeviceBuffer<unsigned long long> offsets(n + 1, "pair offsets per Gaussian");
    launch("cellPairCountKernel", cellPairCountKernel, n + 1, st, n, (const PreparedGaussian*)gaussians.data(),
           p.cellSize, nano, offsets.data());
    cubCall(temp, [&](void* t, std::size_t& b) {
        return cub::DeviceScan::ExclusiveSum(t, b, offsets.data(), offsets.data(), n + 1, st);
    });
    unsigned long long pairs = 0;
    SPLATWARP_CUDA_CHECK(cudaMemcpyAsync(&pairs, offsets.data() + n, sizeof(pairs), cudaMemcpyDeviceToHost, st));
    SPLATWARP_CUDA_CHECK(cudaStreamSynchronize(st)); // the pair count sizes the next buffers
    if (pairs >= 0xffffffffull) // cell ranges are 32-bit [start, end)
        throw DeviceMemoryError(msg("sample targets (CUDA): ", pairs, " (cell, Gaussian) pairs exceed 32-bit indices"));

    DeviceBuffer<std::uint32_t> cells(pairs, "pair cells"), owners(pairs, "pair Gaussians");
    DeviceBuffer<std::uint32_t> sortedCells(pairs, "sorted pair cells"), sortedOwners(pairs, "sorted pair Gaussians");
    launch("cellPairFillKernel", cellPairFillKernel, n, st, n, (const PreparedGaussian*)gaussians.data(), p.cellSize,
           nano, (const unsigned long long*)offsets.data(), cells.data(), owners.data());
    // Stable LSD radix sort: Gaussians stay ascending within a cell (filled in Gaussian order).
    if (pairs > 0)
        cubCall(temp, [&](void* t, std::size_t& b) {
            return cub::DeviceRadixSort::SortPairs(t, b, (const std::uint32_t*)cells.data(), sortedCells.data(),
                                                   (const std::uint32_t*)owners.data(), sortedOwners.data(), pairs, 0,
                                                   keyBits(p.cells), st);
        });

    // Per-cell ranges; cells without pairs keep [0, 0).
    DeviceBuffer<std::uint32_t> cellStart(p.cells, "cell pair starts"), cellEnd(p.cells, "cell pair ends");
    if (p.cells) {
        SPLATWARP_CUDA_CHECK(cudaMemsetAsync(cellStart.data(), 0, cellStart.bytes(), st));
        SPLATWARP_CUDA_CHECK(cudaMemsetAsync(cellEnd.data(), 0, cellEnd.bytes(), st));
    }
    launch("cellRangeKernel", cellRangeKernel, pairs, st, std::size_t(pairs), (const std::uint32_t*)sortedCells.data(),
           cellStart.data(), cellEnd.data());

    // Targets, one thread per sample.
    DeviceBuffer<float> outF(m * stride, "sample features"), outO(m, "sample opacity");
    DeviceBuffer<std::uint32_t> contributing(m, "contributing pairs per sample");
    DeviceBuffer<unsigned long long> contributingTotal(1, "contributing pair total");
    CellTargetView view;
    view.gaussians = gaussians.data();
    view.sh = sh.data();
    view.shStride = p.shStride;
    view.cutoff = p.cutoff;
    view.positions = positions.data();
    view.sampleCell = sampleCell.data();
    view.cellStart = cellStart.data();
    view.cellEnd = cellEnd.data();
    view.cellGaussians = sortedOwners.data();
    const auto targets = [&](auto kernel, const char* name) {
        launch(name, kernel, m, st, m, view, outF.data(), outO.data(), contributing.data());
    };
    switch (p.shStride) {
    case 3: targets(cellTargetKernel<3>, "cellTargetKernel<3>"); break;
    case 12: targets(cellTargetKernel<12>, "cellTargetKernel<12>"); break;
    case 27: targets(cellTargetKernel<27>, "cellTargetKernel<27>"); break;
    case 48: targets(cellTargetKernel<48>, "cellTargetKernel<48>"); break;
    default: break; // rejected above
    }
    unsigned long long contributed = 0;
    if (m) {
        cubCall(temp, [&](void* t, std::size_t& b) {
            return cub::DeviceReduce::Sum(t, b, (const std::uint32_t*)contributing.data(), contributingTotal.data(), m, st);
        });
        contributingTotal.download(&contributed, 1, st);
    }
    if (features) outF.download(features, m * stride, st);
    if (opacity) outO.download(opacity, m, st);
    if (stats) {
        // Every sample of a cell tests every Gaussian of the cell's list.
        const std::uint64_t perCell = p.cells ? std::uint64_t(m / p.cells) : 0;
        stats->pairsTested += std::uint64_t(pairs) * perCell;
        stats->pairsContributing += contributed;
        stats->binEntries = pairs;
        stats->binCellSize = float(p.cellSize);
    }
}

} // namespace splatwarp::cuda
