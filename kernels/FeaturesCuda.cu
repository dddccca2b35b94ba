// Features on the GPU. Rest sample targets: (cell, Gaussian) pairs from NanoVDB lookups, a
// stable radix sort by cell, per-cell ranges, then one thread per sample summing its cell's
// Gaussians in ascending order (the CPU path's contributing set and order). Arbitrary points:
// the Gaussians' pruning boxes binned (BoxBins), one thread per point summing its bin's
// Gaussians in ascending order. The per-element work is field/CellTargetMath.h, which the
// CPU path and the CPU tests share.
#include "kernels/FeaturesCuda.h"

#include <cub/cub.cuh>

#include <algorithm>
#include <cstdint>
#include <type_traits>
#include <vector>

#include "kernels/BoxBinsCuda.cuh"
#include "kernels/CudaCheck.h"
#include "kernels/CudaLaunch.cuh"
#include "kernels/DeviceBuffer.h"
#include "core/Error.h"
#include "field/CellTargetMath.h"

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
                                 std::uint32_t* tested, std::uint32_t* contributing)
{
    const std::size_t s = globalIndex();
    if (s >= m) return;
    view.shStride = Stride;
    float f[Stride];
    float o = 0.0f;
    tested[s] = cellSampleCandidates(s, view);
    contributing[s] = evaluateCellSample(s, view, f, o);
    for (int k = 0; k < Stride; ++k) features[s * Stride + k] = f[k];
    opacity[s] = o;
}

__global__ void preparedBoxKernel(std::size_t n, const PreparedGaussian* gaussians, float* lo, float* hi)
{
    const std::size_t i = globalIndex();
    if (i >= n) return;
    preparedBox(gaussians[i], lo + 3 * i, hi + 3 * i);
}

/// One thread per point: its bin's boxes (= Gaussian indices, ascending) are the candidates.
template <int Stride>
__global__ void pointFeatureKernel(std::size_t m, const float* points, float inv, const unsigned long long* keys,
                                   const std::uint32_t* boxes, std::size_t entries, const PreparedGaussian* gaussians,
                                   const float* sh, float cutoff, float* features, float* opacity,
                                   std::uint32_t* tested, std::uint32_t* contributing)
{
    const std::size_t p = globalIndex();
    if (p >= m) return;
    const Vec3f x(points[3 * p], points[3 * p + 1], points[3 * p + 2]);
    const unsigned long long key = packKey(binCoord(x.x, inv), binCoord(x.y, inv), binCoord(x.z, inv));
    const std::size_t first = lowerBound(keys, entries, key);
    std::size_t last = first;
    while (last < entries && keys[last] == key) ++last;
    float f[Stride];
    float o = 0.0f;
    contributing[p] = accumulateFeatures(x, boxes + first, last - first, gaussians, sh, Stride, cutoff, f, o);
    tested[p] = std::uint32_t(last - first);
    for (int k = 0; k < Stride; ++k) features[p * Stride + k] = f[k];
    opacity[p] = o;
}

/// Bits of the largest cell index (at least 1): the radix sort looks at no more.
int keyBits(std::size_t cells)
{
    int bits = 1;
    while (bits < 32 && (std::size_t(1) << bits) < cells) ++bits;
    return bits;
}

/// The prepared Gaussians and their SH on the device.
struct DeviceCloud {
    DeviceBuffer<PreparedGaussian> gaussians{"prepared Gaussians"};
    DeviceBuffer<float> sh{"Gaussian SH coefficients"};
    void upload(const PreparedCloudView& c, cudaStream_t st);
};

template <typename T>
void uploadArray(DeviceBuffer<T>& buffer, const T* host, std::size_t n, cudaStream_t stream)
{
    buffer.resize(n);
    if (n) SPLATWARP_CUDA_CHECK(cudaMemcpyAsync(buffer.data(), host, n * sizeof(T), cudaMemcpyHostToDevice, stream));
}

void DeviceCloud::upload(const PreparedCloudView& c, cudaStream_t st)
{
    uploadArray(gaussians, c.gaussians, c.count, st);
    uploadArray(sh, c.sh, c.count * std::size_t(c.shStride), st);
}

void checkStride(int stride, const char* who)
{
    if (stride != 3 && stride != 12 && stride != 27 && stride != 48)
        throw InputError(msg(who, ": unsupported SH stride ", stride, " (degree 0..3)"));
}

/// f(std::integral_constant<int, stride>) for a stride checked by checkStride().
template <typename F>
void dispatchStride(int stride, const F& f)
{
    switch (stride) {
    case 3: f(std::integral_constant<int, 3>()); break;
    case 12: f(std::integral_constant<int, 12>()); break;
    case 27: f(std::integral_constant<int, 27>()); break;
    case 48: f(std::integral_constant<int, 48>()); break;
    default: break;
    }
}

/// Sum of a per-element uint32 counter (one synchronising read-back).
unsigned long long deviceSum(DeviceBuffer<unsigned char>& temp, const std::uint32_t* values, std::size_t n,
                             cudaStream_t st)
{
    if (n == 0) return 0;
    DeviceBuffer<unsigned long long> total(1, "counter total");
    cubCall(temp, [&](void* t, std::size_t& b) { return cub::DeviceReduce::Sum(t, b, values, total.data(), n, st); });
    unsigned long long out = 0;
    total.download(&out, 1, st);
    return out;
}

/// What both evaluators write per point (or sample): features, opacity and the pair counters, and
/// how they hand them back.
struct FeatureOutputs {
    FeatureOutputs(std::size_t m, std::size_t stride)
        : features(m * stride, "features per point"), opacity(m, "opacity per point"), tested(m, "tested pairs per point"),
          contributing(m, "contributing pairs per point"), count(m), stride(stride)
    {
    }
    /// Downloads what the caller asked for and adds the pair counts (summed per point: cells hold
    /// different sample counts where some are fine) to stats.
    void finish(DeviceBuffer<unsigned char>& temp, float* featuresOut, float* opacityOut, FeatureStats* stats,
                cudaStream_t st) const
    {
        const unsigned long long testedTotal = deviceSum(temp, tested.data(), count, st);
        const unsigned long long contributed = deviceSum(temp, contributing.data(), count, st);
        if (featuresOut) features.download(featuresOut, count * stride, st);
        if (opacityOut) opacity.download(opacityOut, count, st);
        if (stats) {
            stats->pairsTested += testedTotal;
            stats->pairsContributing += contributed;
        }
    }
    DeviceBuffer<float> features, opacity;
    DeviceBuffer<std::uint32_t> tested, contributing;
    std::size_t count, stride;
};

/// The inputs of the sample targets on the device. The host arrays outlive the stream
/// synchronisation that follows (downloads synchronise).
struct SampleTargetInputs {
    DeviceBuffer<unsigned char> grid{"NanoVDB cell index grid"};
    DeviceCloud cloud;
    DeviceBuffer<float> positions{"sample positions"};
    DeviceBuffer<std::int32_t> sampleCell{"sample cells"};

    void upload(const SampleTargetsProblem& p, cudaStream_t st)
    {
        uploadArray(grid, static_cast<const unsigned char*>(p.index->data()), p.index->bytes(), st);
        cloud.upload(p.cloud, st);
        uploadArray(positions, p.positions, 3 * p.samples, st);
        uploadArray(sampleCell, p.sampleCell, p.samples, st);
    }
    /// The device copy of the validated host bytes (cudaMalloc aligns far beyond NanoVDB's 32).
    const NanoCellGrid* nano() const { return reinterpret_cast<const NanoCellGrid*>(grid.data()); }
};

/// (cell, Gaussian) pairs sorted by cell (Gaussians ascending within a cell) and each cell's
/// [start, end) in them; cells without pairs keep [0, 0).
struct CellPairs {
    unsigned long long count = 0;
    DeviceBuffer<unsigned long long> offsets{"pair offsets per Gaussian"};
    DeviceBuffer<std::uint32_t> cells{"pair cells"}, owners{"pair Gaussians"};
    DeviceBuffer<std::uint32_t> sortedCells{"sorted pair cells"}, sortedOwners{"sorted pair Gaussians"};
    DeviceBuffer<std::uint32_t> cellStart{"cell pair starts"}, cellEnd{"cell pair ends"};
};

/// Pairs per Gaussian, exclusive scan: sets pairs.count (one synchronising read-back).
void countCellPairs(const SampleTargetsProblem& p, const SampleTargetInputs& in, DeviceBuffer<unsigned char>& temp,
                    CellPairs& pairs, cudaStream_t st)
{
    const std::size_t n = p.cloud.count;
    pairs.offsets.resize(n + 1);
    launch("cellPairCountKernel", cellPairCountKernel, n + 1, st, n, (const PreparedGaussian*)in.cloud.gaussians.data(),
           p.cellSize, in.nano(), pairs.offsets.data());
    cubCall(temp, [&](void* t, std::size_t& b) {
        return cub::DeviceScan::ExclusiveSum(t, b, pairs.offsets.data(), pairs.offsets.data(), n + 1, st);
    });
    SPLATWARP_CUDA_CHECK(
        cudaMemcpyAsync(&pairs.count, pairs.offsets.data() + n, sizeof(pairs.count), cudaMemcpyDeviceToHost, st));
    SPLATWARP_CUDA_CHECK(cudaStreamSynchronize(st)); // the pair count sizes the next buffers
    if (pairs.count >= 0xffffffffull) // cell ranges are 32-bit [start, end)
        throw DeviceLimitError(msg("sample targets (CUDA): ", pairs.count, " (cell, Gaussian) pairs exceed 32-bit indices"));
}

/// Fill the pairs in Gaussian order, sort them by cell, mark each cell's range.
void sortCellPairs(const SampleTargetsProblem& p, const SampleTargetInputs& in, DeviceBuffer<unsigned char>& temp,
                   CellPairs& pairs, cudaStream_t st)
{
    const std::size_t n = p.cloud.count, count = std::size_t(pairs.count);
    for (auto* b : {&pairs.cells, &pairs.owners, &pairs.sortedCells, &pairs.sortedOwners}) b->resize(count);
    launch("cellPairFillKernel", cellPairFillKernel, n, st, n, (const PreparedGaussian*)in.cloud.gaussians.data(),
           p.cellSize, in.nano(), (const unsigned long long*)pairs.offsets.data(), pairs.cells.data(),
           pairs.owners.data());
    // Stable LSD radix sort: Gaussians stay ascending within a cell (filled in Gaussian order).
    if (count > 0)
        cubCall(temp, [&](void* t, std::size_t& b) {
            return cub::DeviceRadixSort::SortPairs(t, b, (const std::uint32_t*)pairs.cells.data(),
                                                   pairs.sortedCells.data(), (const std::uint32_t*)pairs.owners.data(),
                                                   pairs.sortedOwners.data(), count, 0, keyBits(p.cells), st);
        });
    pairs.cellStart.resize(p.cells);
    pairs.cellEnd.resize(p.cells);
    if (p.cells) {
        SPLATWARP_CUDA_CHECK(cudaMemsetAsync(pairs.cellStart.data(), 0, pairs.cellStart.bytes(), st));
        SPLATWARP_CUDA_CHECK(cudaMemsetAsync(pairs.cellEnd.data(), 0, pairs.cellEnd.bytes(), st));
    }
    launch("cellRangeKernel", cellRangeKernel, count, st, count, (const std::uint32_t*)pairs.sortedCells.data(),
           pairs.cellStart.data(), pairs.cellEnd.data());
}

/// What the per-sample kernel reads: the inputs and the sorted pairs.
CellTargetView cellTargetView(const SampleTargetsProblem& p, const SampleTargetInputs& in, const CellPairs& pairs)
{
    CellTargetView view;
    view.gaussians = in.cloud.gaussians.data();
    view.sh = in.cloud.sh.data();
    view.shStride = p.cloud.shStride;
    view.cutoff = p.cloud.cutoff;
    view.positions = in.positions.data();
    view.sampleCell = in.sampleCell.data();
    view.cellStart = pairs.cellStart.data();
    view.cellEnd = pairs.cellEnd.data();
    view.cellGaussians = pairs.sortedOwners.data();
    return view;
}

} // namespace

void checkSampleTargets(const SampleTargetsProblem& p)
{
    if (!p.index || !nanoCellGrid(*p.index))
        throw InputError("sample targets (CUDA): the cell index grid is not a NanoVDB Int32 grid");
    checkStride(p.cloud.shStride, "sample targets (CUDA)");
    if (!(p.cellSize > 0.0)) throw InputError(msg("sample targets (CUDA): bad cell size ", p.cellSize));
    if (p.samples > 0 && (p.cells == 0 || !p.positions || !p.sampleCell))
        throw InputError(msg("sample targets (CUDA): ", p.samples, " samples without cells, positions or sample cells"));
    // Cells may hold different sample counts (fine cells): the kernel works per sample, so only
    // each sample's cell must exist (it indexes the per-cell ranges).
    for (std::size_t s = 0; s < p.samples; ++s)
        if (p.sampleCell[s] < 0 || std::size_t(p.sampleCell[s]) >= p.cells)
            throw InputError(msg("sample targets (CUDA): sample ", s, " is in cell ", p.sampleCell[s], " of ", p.cells));
    if (p.cloud.count > 0 && (!p.cloud.gaussians || !p.cloud.sh))
        throw InputError("sample targets (CUDA): Gaussians without prepared kernels or SH");
}

void evaluateSampleTargetsCuda(const SampleTargetsProblem& p, float* features, float* opacity, FeatureStats* stats)
{
    checkSampleTargets(p);
    const std::size_t m = p.samples, stride = std::size_t(p.cloud.shStride);
    StreamHolder holder;
    const cudaStream_t st = holder.stream;
    SampleTargetInputs in;
    in.upload(p, st);
    DeviceBuffer<unsigned char> temp("CUB temporary storage");
    CellPairs pairs;
    countCellPairs(p, in, temp, pairs, st);
    sortCellPairs(p, in, temp, pairs, st);

    // Targets, one thread per sample.
    FeatureOutputs out(m, stride);
    const CellTargetView view = cellTargetView(p, in, pairs);
    dispatchStride(p.cloud.shStride, [&](auto tag) {
        launch("cellTargetKernel", cellTargetKernel<decltype(tag)::value>, m, st, m, view, out.features.data(),
               out.opacity.data(), out.tested.data(), out.contributing.data());
    });
    out.finish(temp, features, opacity, stats, st);
    if (stats) {
        stats->binEntries = pairs.count;
        stats->binCellSize = float(p.cellSize);
    }
}

void evaluateFeaturesCuda(const FeaturePointsProblem& p, float* features, float* opacity, FeatureStats* stats)
{
    checkStride(p.cloud.shStride, "features (CUDA)");
    if ((p.count > 0 && !p.points) || (p.cloud.count > 0 && (!p.cloud.gaussians || !p.cloud.sh)))
        throw InputError("features (CUDA): missing points, prepared Gaussians or SH");
    if (p.cloud.count > 0xffffffffull) throw DeviceLimitError("features (CUDA): too many Gaussians for 32-bit indices");
    const std::size_t n = p.cloud.count, m = p.count, stride = std::size_t(p.cloud.shStride);
    StreamHolder holder;
    const cudaStream_t st = holder.stream;
    DeviceCloud cloud;
    cloud.upload(p.cloud, st);
    DeviceBuffer<float> points("feature points");
    uploadArray(points, p.points, 3 * m, st);

    // Bins of the pruning boxes; box k is Gaussian k (never-contributing ones are empty boxes).
    DeviceBuffer<float> lo(3 * n, "Gaussian boxes (lo)"), hi(3 * n, "Gaussian boxes (hi)");
    launch("preparedBoxKernel", preparedBoxKernel, n, st, n, (const PreparedGaussian*)cloud.gaussians.data(), lo.data(),
           hi.data());
    BoxBins bins;
    const bool any = bins.build(n, lo.data(), hi.data(), st, "features (CUDA)");

    FeatureOutputs out(m, stride);
    dispatchStride(p.cloud.shStride, [&](auto tag) {
        launch("pointFeatureKernel", pointFeatureKernel<decltype(tag)::value>, m, st, m, (const float*)points.data(),
               any ? bins.inv() : 1.0f, bins.keys(), bins.boxes(), any ? bins.entries() : std::size_t(0),
               (const PreparedGaussian*)cloud.gaussians.data(), (const float*)cloud.sh.data(), p.cloud.cutoff,
               out.features.data(), out.opacity.data(), out.tested.data(), out.contributing.data());
    });
    DeviceBuffer<unsigned char> temp("CUB temporary storage");
    out.finish(temp, features, opacity, stats, st);
    if (stats) {
        stats->binEntries = any ? bins.entries() : 0;
        stats->binCellSize = any ? 1.0f / bins.inv() : 0.0f;
    }
}

} // namespace splatwarp::cuda
