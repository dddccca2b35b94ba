// Stage II on the GPU (see StageTwoCuda.h). Mirrors stage2/StageTwo.cpp step by step; the
// per-element maths is the shared host/device code (PairGradients.h, PreparedGaussian.h,
// StageTwoSetup.h, Coverage.h). Notation: S used samples, G moving Gaussians, P coverage pairs,
// E bin entries, STRIDE = 3 (degree+1)^2 SH floats, PER_G = 11 + STRIDE packed parameters.
#include <math_constants.h>
#include "kernels/StageTwoCuda.h"

#include <cub/cub.cuh>

#include <algorithm>
#include <cmath>
#include <memory>
#include <numeric>

#include "kernels/CudaCheck.h"
#include "kernels/CudaLaunch.cuh"
#include "kernels/BoxBinsCuda.cuh"
#include "kernels/DeviceBuffer.h"
#include "core/Progress.h"
#include "stage2/PairGradients.h"
#include "stage2/Coverage.h"
#include "stage2/StageTwoSetup.h"
#include "stage2/StageTwoLoop.h"
#include "stage2/StageTwoParams.h"

namespace splatwarp::cuda {
namespace {

constexpr int kWarp = 32;         // CUDA warp width (backward: one warp per Gaussian)
constexpr int kReduceBlocks = 264; // energy reduction partials: 2 per SM of an H100 (132 SMs); fixed so sums are deterministic
// Packed parameters per moving Gaussian: stage2/StageTwoParams.h (shared with the CPU solver).
constexpr int kSh = kParamSh;

// ---------------------------------------------------------------------------------------------
// Small host helpers

/// GPU time per phase from CUDA events (the loop never waits, so host clocks would only see
/// launch costs). The times of finished phases are summed at each synchronisation the loop makes
/// anyway (harvest()), and their events reused: a few events in all, not ~10 per iteration.
class PhaseTimer {
public:
    enum Phase { Coverage, Forward, Backward, Update, Count };
    explicit PhaseTimer(cudaStream_t stream) : mStream(stream) {}
    ~PhaseTimer()
    {
        for (const Mark& m : mMarks) {
            cudaEventDestroy(m.start);
            cudaEventDestroy(m.end);
        }
        for (cudaEvent_t e : mPool) cudaEventDestroy(e);
    }
    PhaseTimer(const PhaseTimer&) = delete;
    PhaseTimer& operator=(const PhaseTimer&) = delete;
    void begin(Phase p)
    {
        const cudaEvent_t start = take();
        cudaEvent_t end = nullptr;
        try {
            end = take();
        } catch (...) {
            mPool.push_back(start);
            throw;
        }
        mMarks.push_back({p, start, end});
        SPLATWARP_CUDA_CHECK(cudaEventRecord(start, mStream));
    }
    void end() { SPLATWARP_CUDA_CHECK(cudaEventRecord(mMarks.back().end, mStream)); }
    /// Add up the marked phases and keep their events for reuse. Only right after the stream was
    /// synchronised and outside a phase: every recorded event has completed then.
    void harvest()
    {
        for (const Mark& m : mMarks) {
            float t = 0;
            SPLATWARP_CUDA_CHECK(cudaEventElapsedTime(&t, m.start, m.end));
            mMs[m.phase] += double(t);
            mPool.push_back(m.start);
            mPool.push_back(m.end);
        }
        mMarks.clear();
    }
    /// Milliseconds per phase (call after the stream is synchronised).
    void totals(double* ms)
    {
        harvest();
        for (int p = 0; p < Count; ++p) ms[p] = mMs[p];
    }

private:
    struct Mark {
        Phase phase;
        cudaEvent_t start, end;
    };
    cudaEvent_t take()
    {
        if (!mPool.empty()) {
            const cudaEvent_t e = mPool.back();
            mPool.pop_back();
            return e;
        }
        cudaEvent_t e = nullptr;
        SPLATWARP_CUDA_CHECK(cudaEventCreate(&e));
        return e;
    }
    cudaStream_t mStream;
    std::vector<Mark> mMarks;      ///< recorded since the last harvest()
    std::vector<cudaEvent_t> mPool; ///< events of harvested marks, free for reuse
    double mMs[Count] = {};
};

// ---------------------------------------------------------------------------------------------
// Device helpers

// ---------------------------------------------------------------------------------------------
// Kernels: per Gaussian

/// PreparedGaussian of each moving Gaussian from its packed parameters and fixed filter.
__global__ void prepareKernel(std::size_t g, int perG, const float* params /* [G,PER_G] */,
                              const double* filter /* [G,9] */, float cutoff, PreparedGaussian* out /* [G] */)
{
    const std::size_t k = globalIndex();
    if (k >= g) return;
    out[k] = PreparedGaussian::from(
        prepareParams(unpackParams(params + k * std::size_t(perG)), Mat3d::fromRowMajor(filter + 9 * k), double(cutoff)));
}

/// Padded coverage box and slabs of each moving Gaussian (stageTwoCoverageBox/Slabs, as the CPU).
__global__ void boxKernel(std::size_t g, int perG, const float* params /* [G,PER_G] */, const double* filter /* [G,9] */,
                          int steps, double move, StageTwoOptions options, float* lo /* [G,3] */, float* hi /* [G,3] */,
                          CoverageSlabs* slabs /* [G] */)
{
    const std::size_t k = globalIndex();
    if (k >= g) return;
    const GaussianParams<double> p = unpackParams(params + k * std::size_t(perG));
    const Mat3d f = Mat3d::fromRowMajor(filter + 9 * k);
    stageTwoCoverageBox(p, f, steps, move, options, lo + 3 * k, hi + 3 * k);
    stageTwoCoverageSlabs(p, f, steps, move, options, slabs[k]);
}

/// Clears *allHold when a Gaussian has left the reach its coverage was built for
/// (stageTwoCoverageHolds, as the CPU); every writer stores the same 0.
__global__ void holdsKernel(std::size_t g, int perG, const float* params /* [G,PER_G] */, const double* filter /* [G,9] */,
                            float cutoff, const float* lo /* [G,3] */, const float* hi /* [G,3] */,
                            const CoverageSlabs* slabs /* [G] */, int* allHold)
{
    const std::size_t k = globalIndex();
    if (k >= g) return;
    if (!stageTwoCoverageHolds(unpackParams(params + k * std::size_t(perG)), Mat3d::fromRowMajor(filter + 9 * k), double(cutoff),
                               lo + 3 * k, hi + 3 * k, slabs[k]))
        *allHold = 0;
}

// ---------------------------------------------------------------------------------------------
// Kernels: per sample (coverage)

/// Boxes containing each sample, found through its bin cell: count (fill == false) or write
/// the ascending box indices and the pair's sample (fill == true).
template <bool Fill>
__global__ void coverageKernel(std::size_t s, const float* x /* [S,3] */, float inv, const unsigned long long* keys /* [E] sorted */,
                               const std::uint32_t* boxes /* [E] */, std::size_t entries, const float* lo /* [G,3] */,
                               const float* hi /* [G,3] */, const CoverageSlabs* slabs /* [G] */,
                               unsigned long long* countOrOffset /* [S+1] */,
                               std::uint32_t* items /* [P] */, std::uint32_t* pairSample /* [P] */)
{
    const std::size_t j = globalIndex();
    if (j > s) return;
    if (!Fill && j == s) {
        countOrOffset[s] = 0; // the exclusive scan's total lands here
        return;
    }
    if (j == s) return;
    const float* p = x + 3 * j;
    const unsigned long long key = packKey(binCoord(p[0], inv), binCoord(p[1], inv), binCoord(p[2], inv));
    unsigned long long out = Fill ? countOrOffset[j] : 0;
    for (std::size_t e = lowerBound(keys, entries, key); e < entries && keys[e] == key; ++e) {
        const std::uint32_t k = boxes[e];
        if (!insideBox(lo, hi, k, p) || !slabs[k].contains(p)) continue;
        if (Fill) {
            items[out] = k;
            pairSample[out] = std::uint32_t(j);
        }
        ++out;
    }
    if (!Fill) countOrOffset[j] = out;
}

/// Per-Gaussian CSR offsets of the Gaussian-major pair list (sorted by Gaussian).
__global__ void gaussianOffsetsKernel(std::size_t g, const std::uint32_t* sortedBox /* [P] */, std::size_t pairs,
                                      std::uint32_t* offsets /* [G+1] */)
{
    const std::size_t k = globalIndex();
    if (k > g) return;
    offsets[k] = std::uint32_t(lowerBound(sortedBox, pairs, std::uint32_t(k)));
}

__global__ void narrowOffsetsKernel(std::size_t n, const unsigned long long* in, std::uint32_t* out) // [n]
{
    const std::size_t i = globalIndex();
    if (i < n) out[i] = std::uint32_t(in[i]);
}

// ---------------------------------------------------------------------------------------------
// Kernels: forward, energy, backward, Adam

/// Threads per block of the forward kernel: its [block, STRIDE] tile of rows (odd pitch) is
/// 25 KB at stride 48, within the 48 KB of static shared memory.
constexpr int kForwardBlock = 128;

/// F, O of each sample (static part + its candidate Gaussians in ascending index order, no
/// atomics), the loss, dE/dF, dE/dO and the counted pairs. The block's [S, STRIDE] rows (static
/// features, targets, dE/dF, features out) pass through a shared tile, so global memory is read
/// and written in consecutive floats, not one row per thread (where each load instruction of a
/// warp touches 32 cache lines). Tail threads (j >= s) only help with the tile.
template <int STRIDE>
__global__ void __launch_bounds__(kForwardBlock)
    forwardKernel(std::size_t s, const float* x /* [S,3] */, const float* fStatic /* [S,STRIDE] */,
                  const float* oStatic /* [S] */, const std::uint32_t* offsets /* [S+1] */, const std::uint32_t* items /* [P] */,
                  const PreparedGaussian* kernels /* [G] */, const float* params /* [G,PER_G] */,
                  const float* targetF /* [S,STRIDE] */, const float* targetO /* [S] */, float cutoff, float lambda1,
                  float lambda2, float* gF /* [S,STRIDE] */, float* gO /* [S] */, float* energy /* [S,3] */,
                  std::uint32_t* pairCount /* [S] */, float* featuresOut /* [S,STRIDE] or null */,
                  float* opacityOut /* [S] or null */)
{
    constexpr int perG = 11 + STRIDE;
    __shared__ float tile[kForwardBlock * tilePitch<STRIDE>()];
    const std::size_t base = std::size_t(blockIdx.x) * kForwardBlock; // < s: blocksFor(s) blocks
    const int rows = s - base < std::size_t(kForwardBlock) ? int(s - base) : kForwardBlock;
    const std::size_t j = base + threadIdx.x;
    const bool active = int(threadIdx.x) < rows;
    float* row = tile + threadIdx.x * tilePitch<STRIDE>();
    loadTileRows<STRIDE>(fStatic + base * STRIDE, rows, tile);
    __syncthreads();
    float f[STRIDE];
#pragma unroll
    for (int c = 0; c < STRIDE; ++c) f[c] = active ? row[c] : 0.0f;
    float o = 0.0f;
    if (active) {
        o = oStatic[j];
        const Vec3f xj(x[3 * j], x[3 * j + 1], x[3 * j + 2]);
        std::uint32_t counted = 0;
        for (std::uint32_t e = offsets[j]; e < offsets[j + 1]; ++e) {
            const std::uint32_t k = items[e];
            const PreparedGaussian kg = kernels[k];
            const float w = kg.weight(xj - kg.mean, cutoff);
            if (w == 0.0f) continue;
            ++counted;
            o += w;
            const float* h = params + std::size_t(k) * perG + kSh;
#pragma unroll
            for (int c = 0; c < STRIDE; ++c) f[c] += w * __ldg(h + c);
        }
        pairCount[j] = counted;
    }
    if (featuresOut) { // the same for the whole block: its barriers are safe
        __syncthreads();
        if (active) {
#pragma unroll
            for (int c = 0; c < STRIDE; ++c) row[c] = f[c];
            opacityOut[j] = o;
        }
        __syncthreads();
        storeTileRows<STRIDE>(tile, rows, featuresOut + base * STRIDE);
    }
    __syncthreads(); // every thread is done with the tile's static features (or features out)
    loadTileRows<STRIDE>(targetF + base * STRIDE, rows, tile);
    __syncthreads();
    float g[STRIDE];
    if (active) {
        float terms[3], go;
        sampleLoss<float, float>(f, row, o, targetO[j], STRIDE, lambda1, lambda2, g, go, terms);
        gO[j] = go;
        for (int t = 0; t < 3; ++t) energy[3 * j + t] = terms[t];
    }
    __syncthreads(); // every thread has read its targets
    if (active) {
#pragma unroll
        for (int c = 0; c < STRIDE; ++c) row[c] = g[c];
    }
    __syncthreads();
    storeTileRows<STRIDE>(tile, rows, gF + base * STRIDE);
}

/// Energy terms (double) and counted pairs of one forward pass.
struct EnergySum {
    double color, opacity, boundary;
    unsigned long long pairs;
};
struct EnergySumOp {
    __device__ EnergySum operator()(const EnergySum& a, const EnergySum& b) const
    {
        return {a.color + b.color, a.opacity + b.opacity, a.boundary + b.boundary, a.pairs + b.pairs};
    }
};

/// Stage 1 of the deterministic energy reduction: kReduceBlocks partial sums.
__global__ void energyPartialKernel(std::size_t s, const float* energy /* [S,3] */, const std::uint32_t* pairCount /* [S] */,
                                    EnergySum* partial /* [kReduceBlocks] */)
{
    EnergySum a{0, 0, 0, 0};
    for (std::size_t j = globalIndex(); j < s; j += std::size_t(gridDim.x) * blockDim.x) {
        a.color += double(energy[3 * j]);
        a.opacity += double(energy[3 * j + 1]);
        a.boundary += double(energy[3 * j + 2]);
        a.pairs += pairCount[j];
    }
    using BlockReduce = cub::BlockReduce<EnergySum, kBlock>;
    __shared__ typename BlockReduce::TempStorage temp;
    const EnergySum total = BlockReduce(temp).Reduce(a, EnergySumOp());
    if (threadIdx.x == 0) partial[blockIdx.x] = total;
}

/// Stage 2: one block sums the partials into out (the iteration's slot).
__global__ void energyFinalKernel(const EnergySum* partial /* [kReduceBlocks] */, EnergySum* out)
{
    EnergySum a{0, 0, 0, 0};
    for (int b = int(threadIdx.x); b < kReduceBlocks; b += blockDim.x) a = EnergySumOp()(a, partial[b]);
    using BlockReduce = cub::BlockReduce<EnergySum, kBlock>;
    __shared__ typename BlockReduce::TempStorage temp;
    const EnergySum total = BlockReduce(temp).Reduce(a, EnergySumOp());
    if (threadIdx.x == 0) *out = total;
}

__device__ double warpSum(double v)
{
    // Butterfly: every lane ends with the same total, in a fixed order (deterministic).
    for (int offset = kWarp / 2; offset > 0; offset /= 2) v += __shfl_xor_sync(0xffffffffu, v, offset);
    return v;
}

/// One pass of a warp over a Gaussian's pairs (this lane: e = begin, begin + 32, ... < end),
/// summing w dE/dF_c for the SH channels [C0, C0 + CN) into gh and, when WithAcc, the pair
/// backward (dE/dw over every channel, ascending) into acc. Each sum keeps the pair order and
/// its own accumulator, so splitting the channels over passes leaves every bit as in one pass;
/// the weight is recomputed per pass (same operations, same bits).
template <int STRIDE, int C0, int CN, bool WithAcc>
__device__ void backwardPass(std::uint64_t begin, std::uint64_t end, const std::uint32_t* items, const float* x,
                             const PreparedGaussian& kg, const float* h, const float* gF, const float* gO, float cutoff,
                             double* gh /* [CN] */, GaussianAccum<double>& acc)
{
#pragma unroll 1 // one pair at a time: unrolled, the pairs' loads and temporaries would all be live
    for (std::uint64_t e = begin; e < end; e += kWarp) { // 64-bit: e + kWarp would wrap near 2^32 pairs
        const std::uint32_t j = items[e];
        const Vec3f xj(x[3 * std::size_t(j)], x[3 * std::size_t(j) + 1], x[3 * std::size_t(j) + 2]);
        Vec3f ad;
        const float w = kg.weight(xj - kg.mean, cutoff, WithAcc ? &ad : nullptr);
        if (w == 0.0f) continue;
        const float* gfj = gF + std::size_t(j) * STRIDE;
        if constexpr (WithAcc && CN == STRIDE) { // one pass (strides 3, 12, 27): one fused loop
            double gw = gO[j];
#pragma unroll
            for (int c = 0; c < STRIDE; ++c) {
                const double gfc = double(gfj[c]);
                gw += gfc * double(h[c]);
                gh[c] += double(w) * gfc;
            }
            pairBackward<double>(gw, double(w), double(kg.alpha), Vec3d(ad), acc);
            continue;
        }
        if constexpr (WithAcc) {
            double gw = gO[j];
            // Not unrolled in full: the compiler would hoist the Gaussian's 48 SH values (as
            // doubles) out of the pair loop into registers.
#pragma unroll 4
            for (int c = 0; c < STRIDE; ++c) gw += double(gfj[c]) * double(h[c]);
            pairBackward<double>(gw, double(w), double(kg.alpha), Vec3d(ad), acc);
        }
#pragma unroll
        for (int c = 0; c < CN; ++c) gh[c] += double(w) * double(gfj[C0 + c]);
    }
}

/// Warp-sum gh [CN] and store SH channels [C0, C0 + CN) of the gradient row (lane c % 32 writes c).
template <int C0, int CN>
__device__ void storeShGradient(double* gh, int lane, float* out /* [PER_G] */)
{
#pragma unroll
    for (int c = 0; c < CN; ++c) gh[c] = warpSum(gh[c]);
#pragma unroll
    for (int c = 0; c < CN; ++c)
        if ((C0 + c) % kWarp == lane) out[kSh + C0 + c] = float(gh[c]);
}

/// SH channels per pass of the backward. The double accumulators of a whole degree-3 row (48)
/// took the kernel to 168 registers (1 block of 256 threads per SM, 12.5% occupancy); three passes
/// of 16 take 120 (2 blocks, 25%; two passes of 24 spill). Stride 27 takes 128 in one pass (2
/// blocks), strides 3 and 12 fewer.
template <int STRIDE>
constexpr int shChunk()
{
    return STRIDE <= 27 ? STRIDE : 16;
}

/// Passes over the pairs for SH channels [C0, STRIDE), shChunk<STRIDE>() at a time.
template <int STRIDE, int C0>
__device__ void shGradientPasses(std::uint64_t begin, std::uint64_t end, const std::uint32_t* items, const float* x,
                                 const PreparedGaussian& kg, const float* gF, float cutoff, int lane, float* out)
{
    constexpr int CN = STRIDE - C0 < shChunk<STRIDE>() ? STRIDE - C0 : shChunk<STRIDE>();
    double gh[CN];
#pragma unroll
    for (int c = 0; c < CN; ++c) gh[c] = 0;
    GaussianAccum<double> unused;
    backwardPass<STRIDE, C0, CN, false>(begin, end, items, x, kg, nullptr, gF, nullptr, cutoff, gh, unused);
    storeShGradient<C0, CN>(gh, lane, out);
    if constexpr (C0 + CN < STRIDE) shGradientPasses<STRIDE, C0 + CN>(begin, end, items, x, kg, gF, cutoff, lane, out);
}

/// Gradient of each moving Gaussian: one warp gathers its pairs from the Gaussian-major list
/// (lanes stride over the pairs, double accumulators, butterfly sums): no atomics. The first
/// pass sums the geometry and opacity terms and the first shChunk() SH channels, more passes
/// (stride 48) the other channels (see backwardPass).
template <int STRIDE>
__global__ void __launch_bounds__(kBlock) backwardKernel(std::size_t g, const std::uint32_t* offsets /* [G+1] */,
                                                         const std::uint32_t* items /* [P] */, const float* x /* [S,3] */,
                                                         const PreparedGaussian* kernels /* [G] */,
                                                         const float* params /* [G,PER_G] */, const float* gF /* [S,STRIDE] */,
                                                         const float* gO /* [S] */, float cutoff, float* grad /* [G,PER_G] */)
{
    constexpr int perG = 11 + STRIDE;
    constexpr int CN = shChunk<STRIDE>();
    const std::size_t k = globalIndex() / kWarp;
    const int lane = int(threadIdx.x) % kWarp;
    if (k >= g) return; // whole warps leave together (blockDim is a multiple of the warp)
    const PreparedGaussian kg = kernels[k];
    const std::uint64_t begin = std::uint64_t(offsets[k]) + std::uint64_t(lane), end = offsets[k + 1];
    float* out = grad + k * perG;
    GaussianAccum<double> acc;
    double gh[CN];
#pragma unroll
    for (int c = 0; c < CN; ++c) gh[c] = 0;
    backwardPass<STRIDE, 0, CN, true>(begin, end, items, x, kg, params + k * perG + kSh, gF, gO, cutoff, gh, acc);
    storeShGradient<0, CN>(gh, lane, out);
    for (int a = 0; a < 3; ++a) acc.mean[a] = warpSum(acc.mean[a]);
    for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) acc.sigma.m[a][b] = warpSum(acc.sigma.m[a][b]);
    acc.alpha = warpSum(acc.alpha);
    if (lane == 0) packGradient(paramBackward(unpackParams(params + k * perG), acc), out);
    if constexpr (CN < STRIDE) shGradientPasses<STRIDE, CN>(begin, end, items, x, kg, gF, cutoff, lane, out);
}

/// Adam on each moving Gaussian's packed row: adamStepRow, the CPU's arithmetic (this file is
/// compiled with -fmad=false, so no multiply-add is contracted where the CPU has none).
__global__ void adamKernel(std::size_t g, int perG, float* params /* [G,PER_G] */, const float* grad /* [G,PER_G] */,
                           float* m /* [G,PER_G] */, float* v /* [G,PER_G] */, const double* filter /* [G,9] */,
                           AdamStep adam, StepRates lr, float maxMeanStep, double* decrease /* [G] */)
{
    const std::size_t k = globalIndex();
    if (k >= g) return;
    const std::size_t i = k * std::size_t(perG);
    decrease[k] =
        adamStepRow(adam, lr, Mat3d::fromRowMajor(filter + 9 * k), maxMeanStep, perG, params + i, m + i, v + i, grad + i);
}

// ---------------------------------------------------------------------------------------------
// The solver: device state of one Stage II run, driven by the shared loop (stage2/StageTwoLoop.h).

class Solver final : public StageTwoSolver {
public:
    Solver(const GaussianCloud& cloud, const SampleSet& samples, const std::vector<std::uint8_t>& moving,
           const std::vector<std::int32_t>& gaussianCell, const StageTwoOptions& options)
        : mOptions(options), mSetup(setupStageTwo(cloud, samples, moving, gaussianCell, options)),
          mStride(cloud.shStride()), mPerG(packedParamCount(cloud.shStride())), mS(mSetup.used.size()),
          mG(mSetup.moving.size()), mTimer(mStream.stream)
    {
        if (mStride > 48 || mStride % 3 != 0) throw InputError(msg("Stage II (CUDA): unsupported SH stride ", mStride));
        mSkipped = samples.sampleCount() - mS;
        upload(cloud, samples);
        mSetupMs = mSetupWatch.ms();
    }

    Device device() const override { return Device::Cuda; }
    void describe(StageTwoReport& r) const override
    {
        r.samplesUsed = mS;
        r.samplesSkipped = mSkipped;
        r.sceneExtent = mSetup.sceneExtent;
        r.movingGaussians = mG;
        r.msSetup = mSetupMs;
    }
    const StageTwoSetup& setup() const { return mSetup; }
    int stride() const { return mStride; }
    cudaStream_t stream() const { return mStream.stream; }

    void prepare() override
    {
        mTimer.begin(PhaseTimer::Forward);
        launch("prepareKernel", prepareKernel, mG, stream(), mG, mPerG, (const float*)mParams.data(),
               (const double*)mFilter.data(), mOptions.cutoff, mPrepared.data());
        mTimer.end();
    }

    void rebuildCoverage(int iteration, bool) override // always whole: the per-sample lists are rebuilt by sorting
    {
        mTimer.begin(PhaseTimer::Coverage);
        coverage(iteration);
        mTimer.end();
    }

    bool coverageHolds() override
    {
        if (mG == 0) return true;
        mTimer.begin(PhaseTimer::Coverage);
        mAllHold.resize(1);
        SPLATWARP_CUDA_CHECK(cudaMemsetAsync(mAllHold.data(), 1, sizeof(int), stream())); // any non-zero: holds
        launch("holdsKernel", holdsKernel, mG, stream(), mG, mPerG, (const float*)mParams.data(),
               (const double*)mFilter.data(), mOptions.cutoff, (const float*)mBoxLo.data(), (const float*)mBoxHi.data(),
               (const CoverageSlabs*)mSlabs.data(), mAllHold.data());
        mTimer.end();
        int all = 0;
        mAllHold.download(&all, 1, stream());
        return all != 0;
    }

    std::uint64_t coveragePairs() const override { return mPairs; }

    StageTwoEnergy forward(int iteration, std::uint64_t& pairs) override
    {
        forwardInto(nullptr, nullptr);
        EnergySum sum;
        mSum.download(&sum, 1, stream());
        mTimer.harvest(); // the download waited: every phase so far has finished
        StageTwoEnergy e;
        e.iteration = iteration;
        e.color = sum.color;
        e.opacity = sum.opacity;
        e.boundary = sum.boundary;
        e.total = e.color + e.opacity + e.boundary;
        pairs = sum.pairs;
        return e;
    }

    /// The forward kernels; features and opacity per used sample also go to the given buffers.
    void forwardInto(float* featuresOut, float* opacityOut)
    {
        mTimer.begin(PhaseTimer::Forward);
        dispatchStride([&](auto strideTag) {
            constexpr int kStride = decltype(strideTag)::value;
            launch<kForwardBlock>("forwardKernel", forwardKernel<kStride>, mS, stream(), mS, (const float*)mX.data(),
                   (const float*)mFStatic.data(), (const float*)mOStatic.data(), (const std::uint32_t*)mSampleOffsets.data(),
                   (const std::uint32_t*)mSampleItems.data(), (const PreparedGaussian*)mPrepared.data(),
                   (const float*)mParams.data(), (const float*)mTargetF.data(), (const float*)mTargetO.data(),
                   mOptions.cutoff, mOptions.lambdaOpacity, mOptions.boundaryWeight, mGF.data(), mGO.data(),
                   mEnergy.data(), mPairCount.data(), featuresOut, opacityOut);
        });
        energyPartialKernel<<<kReduceBlocks, kBlock, 0, stream()>>>(mS, mEnergy.data(), mPairCount.data(), mPartial.data());
        SPLATWARP_CUDA_CHECK_LAUNCH("energyPartialKernel");
        energyFinalKernel<<<1, kBlock, 0, stream()>>>(mPartial.data(), mSum.data());
        SPLATWARP_CUDA_CHECK_LAUNCH("energyFinalKernel");
        mTimer.end();
    }

    void backward() override
    {
        mTimer.begin(PhaseTimer::Backward);
        dispatchStride([&](auto strideTag) {
            constexpr int kStride = decltype(strideTag)::value;
            launch("backwardKernel", backwardKernel<kStride>, mG * kWarp, stream(), mG,
                   (const std::uint32_t*)mGaussianOffsets.data(), (const std::uint32_t*)mGaussianItems.data(),
                   (const float*)mX.data(), (const PreparedGaussian*)mPrepared.data(), (const float*)mParams.data(),
                   (const float*)mGF.data(), (const float*)mGO.data(), mOptions.cutoff, mGrad.data());
        });
        mTimer.end();
    }

    double step(const StageTwoStep& s) override
    {
        mTimer.begin(PhaseTimer::Update);
        const StepRates lr = StepRates::forStep(mOptions, s, mSetup.sceneExtent);
        launch("adamKernel", adamKernel, mG, stream(), mG, mPerG, mParams.data(), (const float*)mGrad.data(),
               mAdamM.data(), mAdamV.data(), (const double*)mFilter.data(), AdamStep::at(mOptions, s.adamStep), lr,
               mOptions.maxMeanStep, mRowDecrease.data());
        // Summed on the host in row order, as the CPU solver does: the step rule's decision is
        // the same on both devices.
        const std::vector<double> rows = mRowDecrease.download(stream());
        mTimer.end();
        return std::accumulate(rows.begin(), rows.end(), 0.0);
    }

    void saveIterate() override
    {
        copyBuffer(mKeptParams, mParams);
        copyBuffer(mKeptM, mAdamM);
        copyBuffer(mKeptV, mAdamV);
    }
    void restoreIterate() override
    {
        copyBuffer(mParams, mKeptParams);
        copyBuffer(mAdamM, mKeptM);
        copyBuffer(mAdamV, mKeptV);
    }

    void writeTo(GaussianCloud& cloud) const override
    {
        const std::vector<float> params = mParams.download(stream());
        for (std::size_t k = 0; k < mG; ++k) unpackGaussian(params.data() + k * std::size_t(mPerG), cloud, mSetup.moving[k]);
    }

    StageTwoPhaseTimes times() const override
    {
        SPLATWARP_CUDA_CHECK(cudaStreamSynchronize(stream()));
        double ms[PhaseTimer::Count];
        mTimer.totals(ms);
        return {ms[PhaseTimer::Coverage], ms[PhaseTimer::Forward], ms[PhaseTimer::Backward], ms[PhaseTimer::Update]};
    }
    std::uint64_t peakDeviceBytes() const override { return deviceBytesPeak(); }

    /// Fill a probe with the coverage and gradients (waits).
    void downloadProbe(StageTwoCudaProbe& p) const
    {
        const cudaStream_t st = stream();
        p.boxLo = mBoxLo.download(st);
        p.boxHi = mBoxHi.download(st);
        p.slabs = mSlabs.download(st);
        p.sampleOffsets = mSampleOffsets.download(st);
        p.sampleItems.resize(mPairs);
        mSampleItems.download(p.sampleItems.data(), mPairs, st);
        p.gaussianOffsets = mGaussianOffsets.download(st);
        p.gaussianItems.resize(mPairs);
        mGaussianItems.download(p.gaussianItems.data(), mPairs, st);
        p.gradF = mGF.download(st);
        p.gradO = mGO.download(st);
        p.grad = mGrad.download(st);
    }

private:
    void upload(const GaussianCloud& cloud, const SampleSet& samples);
    void coverage(int iteration);
    void copyBuffer(DeviceBuffer<float>& to, const DeviceBuffer<float>& from)
    {
        to.resize(from.size());
        if (from.size() > 0)
            SPLATWARP_CUDA_CHECK(cudaMemcpyAsync(to.data(), from.data(), from.size() * sizeof(float), cudaMemcpyDeviceToDevice,
                                                 stream()));
    }
    template <typename F>
    void dispatchStride(const F& f) const
    {
        switch (mStride) {
        case 3: f(std::integral_constant<int, 3>()); break;
        case 12: f(std::integral_constant<int, 12>()); break;
        case 27: f(std::integral_constant<int, 27>()); break;
        case 48: f(std::integral_constant<int, 48>()); break;
        default: throw InputError(msg("Stage II (CUDA): unsupported SH stride ", mStride));
        }
    }
    /// Run a CUB device algorithm with the shared temporary storage (size query, then run).
    template <typename F>
    void cubCall(const F& f)
    {
        std::size_t bytes = 0;
        SPLATWARP_CUDA_CHECK(f(nullptr, bytes));
        mCubTemp.resize(std::max<std::size_t>(bytes, 1));
        SPLATWARP_CUDA_CHECK(f(mCubTemp.data(), bytes));
    }
    void clearPairs()
    {
        mPairs = 0;
        mSampleOffsets.resize(mS + 1);
        SPLATWARP_CUDA_CHECK(cudaMemsetAsync(mSampleOffsets.data(), 0, mSampleOffsets.bytes(), stream()));
        mGaussianOffsets.resize(mG + 1);
        SPLATWARP_CUDA_CHECK(cudaMemsetAsync(mGaussianOffsets.data(), 0, mGaussianOffsets.bytes(), stream()));
    }

    Stopwatch mSetupWatch;
    StageTwoOptions mOptions;
    StageTwoSetup mSetup;
    int mStride, mPerG;
    std::size_t mS, mG, mSkipped = 0;
    double mSetupMs = 0;
    StreamHolder mStream;
    mutable PhaseTimer mTimer;
    std::uint64_t mPairs = 0;

    DeviceBuffer<float> mX{"sample positions"}, mFStatic{"static features"}, mOStatic{"static opacity"},
        mTargetF{"target features"}, mTargetO{"target opacity"}, mParams{"Gaussian parameters"},
        mGrad{"parameter gradients"}, mAdamM{"Adam first moments"}, mAdamV{"Adam second moments"},
        mGF{"feature gradients"}, mGO{"opacity gradients"}, mEnergy{"per-sample energies"},
        mBoxLo{"coverage boxes"}, mBoxHi{"coverage boxes"}, mKeptParams{"kept-iterate parameters"},
        mKeptM{"kept-iterate Adam moments"}, mKeptV{"kept-iterate Adam moments"};
    DeviceBuffer<CoverageSlabs> mSlabs{"coverage slabs"};
    DeviceBuffer<double> mFilter{"low-pass filters"}, mRowDecrease{"step decreases"};
    DeviceBuffer<PreparedGaussian> mPrepared{"prepared Gaussians"};
    BoxBins mBins;
    DeviceBuffer<unsigned long long> mSampleCount{"coverage counts"};
    DeviceBuffer<std::uint32_t>
        mSampleOffsets{"coverage offsets"}, mSampleItems{"coverage pairs"}, mPairSample{"coverage pair samples"},
        mGaussianKeys{"Gaussian-major pair keys"}, mGaussianItems{"Gaussian-major pairs"},
        mGaussianOffsets{"Gaussian-major offsets"}, mPairCount{"per-sample pair counts"};
    DeviceBuffer<EnergySum> mPartial{"energy partial sums"}, mSum{"energy sum"};
    DeviceBuffer<int> mAllHold{"coverage holds flag"};
    DeviceBuffer<unsigned char> mCubTemp{"CUB temporary storage"};
};

/// Gather what the loop needs for the used samples and the moving Gaussians, upload once.
void Solver::upload(const GaussianCloud& cloud, const SampleSet& samples)
{
    const cudaStream_t st = stream();
    std::vector<float> targetF(mS * std::size_t(mStride)), targetO(mS);
    for (std::size_t k = 0; k < mS; ++k) {
        const std::size_t j = mSetup.used[k];
        std::copy_n(samples.targetF.data() + j * std::size_t(mStride), mStride, targetF.data() + k * std::size_t(mStride));
        targetO[k] = samples.targetO[j];
    }
    std::vector<float> params(mG * std::size_t(mPerG));
    std::vector<double> filter(9 * mG);
    for (std::size_t k = 0; k < mG; ++k) {
        const std::size_t i = mSetup.moving[k];
        packGaussian(cloud, i, params.data() + k * std::size_t(mPerG));
        for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b) filter[9 * k + std::size_t(3 * a + b)] = mSetup.filter[i].m[a][b];
    }
    mX.upload(mSetup.x, st);
    mFStatic.upload(mSetup.fStatic, st);
    mOStatic.upload(mSetup.oStatic, st);
    mTargetF.upload(targetF, st);
    mTargetO.upload(targetO, st);
    mParams.upload(params, st);
    mFilter.upload(filter, st);
    mPrepared.resize(mG);
    mBoxLo.resize(3 * mG);
    mBoxHi.resize(3 * mG);
    mSlabs.resize(mG);
    mGrad.resize(mG * std::size_t(mPerG));
    mAdamM.resize(mG * std::size_t(mPerG));
    mAdamV.resize(mG * std::size_t(mPerG));
    mRowDecrease.resize(mG);
    mGF.resize(mS * std::size_t(mStride));
    mGO.resize(mS);
    mEnergy.resize(3 * mS);
    mPairCount.resize(mS);
    mPartial.resize(kReduceBlocks);
    mSum.resize(1);
    if (mAdamM.size() > 0) {
        SPLATWARP_CUDA_CHECK(cudaMemsetAsync(mAdamM.data(), 0, mAdamM.bytes(), st));
        SPLATWARP_CUDA_CHECK(cudaMemsetAsync(mAdamV.data(), 0, mAdamV.bytes(), st));
    }
    // The uploads read host vectors that die with this function: wait for them.
    SPLATWARP_CUDA_CHECK(cudaStreamSynchronize(st));
}

/// Coverage in deformed space (boxes and slabs, as the CPU): bins by sorting (cell key, box)
/// entries, samples look up their cell, per-sample lists ascending; then the pairs sorted by
/// Gaussian (stable, so each Gaussian's samples ascend). Reads back two counts.
void Solver::coverage(int iteration)
{
    const cudaStream_t st = stream();
    const int steps = coverageReachSteps(mOptions, iteration);
    const double move = double(steps) * double(stageTwoPositionRate(mOptions, iteration, mSetup.sceneExtent));
    launch("boxKernel", boxKernel, mG, st, mG, mPerG, (const float*)mParams.data(), (const double*)mFilter.data(), steps,
           move, mOptions, mBoxLo.data(), mBoxHi.data(), mSlabs.data());
    if (mG == 0 || mS == 0 ||
        !mBins.build(mG, (const float*)mBoxLo.data(), (const float*)mBoxHi.data(), st, "Stage II (CUDA) coverage")) {
        clearPairs();
        return;
    }
    const float inv = mBins.inv();
    const std::size_t entries = mBins.entries();
    // Samples: count, scan, fill.
    mSampleCount.resize(mS + 1);
    launch("coverageKernel<count>", coverageKernel<false>, mS + 1, st, mS, (const float*)mX.data(), inv, mBins.keys(),
           mBins.boxes(), entries, (const float*)mBoxLo.data(), (const float*)mBoxHi.data(),
           (const CoverageSlabs*)mSlabs.data(), mSampleCount.data(), (std::uint32_t*)nullptr, (std::uint32_t*)nullptr);
    cubCall([&](void* t, std::size_t& b) {
        return cub::DeviceScan::ExclusiveSum(t, b, mSampleCount.data(), mSampleCount.data(), mS + 1, st);
    });
    unsigned long long pairs = 0;
    SPLATWARP_CUDA_CHECK(cudaMemcpyAsync(&pairs, mSampleCount.data() + mS, sizeof(pairs), cudaMemcpyDeviceToHost, st));
    SPLATWARP_CUDA_CHECK(cudaStreamSynchronize(st));
    if (pairs > 0xffffffffull) // the CPU's per-block lists are n^3 times shorter: Auto runs it there
        throw DeviceLimitError(msg("Stage II coverage has ", pairs, " pairs; too many for 32-bit indices"));
    mPairs = pairs;
    mSampleItems.resize(pairs);
    mPairSample.resize(pairs);
    mGaussianKeys.resize(pairs);
    mGaussianItems.resize(pairs);
    launch("coverageKernel<fill>", coverageKernel<true>, mS, st, mS, (const float*)mX.data(), inv, mBins.keys(),
           mBins.boxes(), entries, (const float*)mBoxLo.data(), (const float*)mBoxHi.data(),
           (const CoverageSlabs*)mSlabs.data(), mSampleCount.data(), mSampleItems.data(), mPairSample.data());
    mSampleOffsets.resize(mS + 1);
    launch("narrowOffsetsKernel", narrowOffsetsKernel, mS + 1, st, mS + 1, (const unsigned long long*)mSampleCount.data(),
           mSampleOffsets.data());
    // Gaussian-major list: pairs (in sample order) sorted by box, stable.
    int bits = 1;
    while (bits < 32 && (std::size_t(1) << bits) < mG) ++bits;
    if (pairs > 0)
        cubCall([&](void* t, std::size_t& b) {
            return cub::DeviceRadixSort::SortPairs(t, b, (const std::uint32_t*)mSampleItems.data(), mGaussianKeys.data(),
                                                   (const std::uint32_t*)mPairSample.data(), mGaussianItems.data(), pairs, 0,
                                                   bits, st);
        });
    mGaussianOffsets.resize(mG + 1);
    launch("gaussianOffsetsKernel", gaussianOffsetsKernel, mG + 1, st, mG, (const std::uint32_t*)mGaussianKeys.data(),
           std::size_t(pairs), mGaussianOffsets.data());
}

template <typename Kernel>
KernelOccupancy occupancyOf(const char* name, Kernel kernel, int blockSize, int maxThreadsPerSm)
{
    cudaFuncAttributes a{};
    SPLATWARP_CUDA_CHECK(cudaFuncGetAttributes(&a, kernel));
    KernelOccupancy o;
    o.name = name;
    o.blockSize = blockSize;
    o.registers = a.numRegs;
    o.localBytes = a.localSizeBytes;
    o.sharedBytes = a.sharedSizeBytes;
    SPLATWARP_CUDA_CHECK(cudaOccupancyMaxActiveBlocksPerMultiprocessor(&o.blocksPerSm, kernel, blockSize, 0));
    o.occupancy = double(o.blocksPerSm) * double(blockSize) / double(maxThreadsPerSm);
    return o;
}

template <int STRIDE>
void addStrideKernels(std::vector<KernelOccupancy>& out, int maxThreadsPerSm)
{
    const std::string s = std::to_string(STRIDE);
    out.push_back(occupancyOf(("forwardKernel<" + s + ">").c_str(), forwardKernel<STRIDE>, kForwardBlock, maxThreadsPerSm));
    out.push_back(occupancyOf(("backwardKernel<" + s + ">").c_str(), backwardKernel<STRIDE>, kBlock, maxThreadsPerSm));
}

} // namespace

std::vector<KernelOccupancy> stageTwoKernelOccupancy()
{
    int device = 0, maxThreads = 0;
    SPLATWARP_CUDA_CHECK(cudaGetDevice(&device));
    SPLATWARP_CUDA_CHECK(cudaDeviceGetAttribute(&maxThreads, cudaDevAttrMaxThreadsPerMultiProcessor, device));
    std::vector<KernelOccupancy> out;
    addStrideKernels<3>(out, maxThreads);
    addStrideKernels<12>(out, maxThreads);
    addStrideKernels<27>(out, maxThreads);
    addStrideKernels<48>(out, maxThreads);
    // The rest run at kBlock (energyFinalKernel as one block: listed for its registers).
    const auto add = [&](const char* name, auto kernel) { out.push_back(occupancyOf(name, kernel, kBlock, maxThreads)); };
    add("prepareKernel", prepareKernel);
    add("boxKernel", boxKernel);
    add("holdsKernel", holdsKernel);
    add("coverageKernel<count>", coverageKernel<false>);
    add("coverageKernel<fill>", coverageKernel<true>);
    add("gaussianOffsetsKernel", gaussianOffsetsKernel);
    add("narrowOffsetsKernel", narrowOffsetsKernel);
    add("energyPartialKernel", energyPartialKernel);
    add("energyFinalKernel", energyFinalKernel);
    add("adamKernel", adamKernel);
    add("edgeKernel", edgeKernel);
    add("binCountKernel", binCountKernel);
    add("binFillKernel", binFillKernel);
    return out;
}

StageTwoReport optimiseStageTwoCuda(GaussianCloud& cloud, const SampleSet& samples, const std::vector<std::uint8_t>& moving,
                                    const std::vector<std::int32_t>& gaussianCell, const StageTwoOptions& options,
                                    const std::function<void(int, const GaussianCloud&)>& onEval, int evalEvery)
{
    resetDeviceBytesPeak(); // the peak of this run's buffers (the solver's and their growth)
    Solver solver(cloud, samples, moving, gaussianCell, options);
    return runStageTwoLoop(solver, cloud, options, onEval, evalEvery);
}

StageTwoCudaProbe probeStageTwoCuda(const GaussianCloud& cloud, const SampleSet& samples,
                                    const std::vector<std::uint8_t>& moving,
                                    const std::vector<std::int32_t>& gaussianCell, const StageTwoOptions& options)
{
    StageTwoOptions o = options;
    o.iterations = std::max(o.iterations, 1); // the coverage boxes of a run that takes steps
    Solver solver(cloud, samples, moving, gaussianCell, o);
    StageTwoCudaProbe p;
    p.used = solver.setup().used;
    p.moving = solver.setup().moving;
    const std::size_t s = p.used.size();
    DeviceBuffer<float> features(s * std::size_t(solver.stride()), "probe features"), opacity(s, "probe opacity");
    solver.prepare();
    solver.rebuildCoverage(0, false);
    solver.forwardInto(features.data(), opacity.data());
    solver.backward();
    p.energy = solver.forward(0, p.pairs); // the same pass again, for its energy (deterministic)
    p.features = features.download(solver.stream());
    p.opacity = opacity.download(solver.stream());
    solver.downloadProbe(p);
    return p;
}

} // namespace splatwarp::cuda
