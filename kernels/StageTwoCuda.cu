// Stage II on the GPU (see StageTwoCuda.h). Mirrors stage2/StageTwo.cpp step by step; the
// per-element maths is the shared host/device code (PairGradients.h, PreparedGaussian.h,
// StageTwoCommon.h). Notation: S used samples, G moving Gaussians, P coverage pairs,
// E bin entries, STRIDE = 3 (degree+1)^2 SH floats, PER_G = 11 + STRIDE packed parameters.
#include <math_constants.h>
#include "StageTwoCuda.h"

#include <cub/cub.cuh>

#include <algorithm>
#include <cmath>
#include <memory>

#include "CudaCheck.h"
#include "CudaLaunch.cuh"
#include "BoxBinsCuda.cuh"
#include "DeviceBuffer.h"
#include "core/Progress.h"
#include "stage2/PairGradients.h"
#include "stage2/StageTwoCommon.h"

namespace splatwarp::cuda {
namespace {

constexpr int kWarp = 32;         // CUDA warp width (backward: one warp per Gaussian)
constexpr int kReduceBlocks = 264; // energy reduction partials: 2 per SM of an H100 (132 SMs); fixed so sums are deterministic
// Packed parameters per moving Gaussian, as the CPU's Adam layout: mean 3, rotation 4, logScale 3, logit 1, SH.
constexpr int kMean = 0, kRot = 3, kLogScale = 7, kLogit = 10, kSh = 11;

// ---------------------------------------------------------------------------------------------
// Small host helpers

/// GPU time per phase from CUDA events (the loop never waits, so host clocks would only see
/// launch costs); summed after the final synchronisation.
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
    }
    void begin(Phase p)
    {
        Mark m{p, nullptr, nullptr};
        SPLATWARP_CUDA_CHECK(cudaEventCreate(&m.start));
        SPLATWARP_CUDA_CHECK(cudaEventCreate(&m.end));
        mMarks.push_back(m);
        SPLATWARP_CUDA_CHECK(cudaEventRecord(m.start, mStream));
    }
    void end() { SPLATWARP_CUDA_CHECK(cudaEventRecord(mMarks.back().end, mStream)); }
    /// Milliseconds per phase (call after the stream is synchronised).
    void totals(double* ms) const
    {
        for (int p = 0; p < Count; ++p) ms[p] = 0;
        for (const Mark& m : mMarks) {
            float t = 0;
            SPLATWARP_CUDA_CHECK(cudaEventElapsedTime(&t, m.start, m.end));
            ms[m.phase] += double(t);
        }
    }

private:
    struct Mark {
        Phase phase;
        cudaEvent_t start, end;
    };
    cudaStream_t mStream;
    std::vector<Mark> mMarks;
};

// ---------------------------------------------------------------------------------------------
// Device helpers

SPLATWARP_HOST_DEVICE GaussianParams<double> unpackParams(const float* p) // p: [PER_G]
{
    GaussianParams<double> g;
    g.mean = Vec3d(p[kMean], p[kMean + 1], p[kMean + 2]);
    g.rotation = Quatd{p[kRot], p[kRot + 1], p[kRot + 2], p[kRot + 3]};
    g.logScale = Vec3d(p[kLogScale], p[kLogScale + 1], p[kLogScale + 2]);
    g.logit = p[kLogit];
    return g;
}

__device__ Mat3d loadFilter(const double* f) // f: [9] row-major
{
    Mat3d m;
    for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) m.m[a][b] = f[3 * a + b];
    return m;
}

// ---------------------------------------------------------------------------------------------
// Kernels: per Gaussian

/// PreparedGaussian of each moving Gaussian from its packed parameters and fixed filter.
__global__ void prepareKernel(std::size_t g, int perG, const float* params /* [G,PER_G] */,
                              const double* filter /* [G,9] */, float cutoff, PreparedGaussian* out /* [G] */)
{
    const std::size_t k = std::size_t(blockIdx.x) * blockDim.x + threadIdx.x;
    if (k >= g) return;
    out[k] = PreparedGaussian::from(
        prepareParams(unpackParams(params + k * std::size_t(perG)), loadFilter(filter + 9 * k), double(cutoff)));
}

/// Padded coverage box of each moving Gaussian (stageTwoCoverageBox, as the CPU).
__global__ void boxKernel(std::size_t g, int perG, const float* params /* [G,PER_G] */, const double* filter /* [G,9] */,
                          int steps, double move, StageTwoOptions options, float* lo /* [G,3] */, float* hi /* [G,3] */)
{
    const std::size_t k = std::size_t(blockIdx.x) * blockDim.x + threadIdx.x;
    if (k >= g) return;
    stageTwoCoverageBox(unpackParams(params + k * std::size_t(perG)), loadFilter(filter + 9 * k), steps, move, options,
                        lo + 3 * k, hi + 3 * k);
}

// ---------------------------------------------------------------------------------------------
// Kernels: per sample (coverage)

/// Boxes containing each sample, found through its bin cell: count (fill == false) or write
/// the ascending box indices and the pair's sample (fill == true).
template <bool Fill>
__global__ void coverageKernel(std::size_t s, const float* x /* [S,3] */, float inv, const unsigned long long* keys /* [E] sorted */,
                               const std::uint32_t* boxes /* [E] */, std::size_t entries, const float* lo /* [G,3] */,
                               const float* hi /* [G,3] */, unsigned long long* countOrOffset /* [S+1] */,
                               std::uint32_t* items /* [P] */, std::uint32_t* pairSample /* [P] */)
{
    const std::size_t j = std::size_t(blockIdx.x) * blockDim.x + threadIdx.x;
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
        if (!insideBox(lo, hi, k, p)) continue;
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
    const std::size_t k = std::size_t(blockIdx.x) * blockDim.x + threadIdx.x;
    if (k > g) return;
    offsets[k] = std::uint32_t(lowerBound(sortedBox, pairs, std::uint32_t(k)));
}

__global__ void narrowOffsetsKernel(std::size_t n, const unsigned long long* in, std::uint32_t* out) // [n]
{
    const std::size_t i = std::size_t(blockIdx.x) * blockDim.x + threadIdx.x;
    if (i < n) out[i] = std::uint32_t(in[i]);
}

// ---------------------------------------------------------------------------------------------
// Kernels: forward, energy, backward, Adam

/// F, O of each sample (static part + its candidate Gaussians in ascending index order, no
/// atomics), the loss, dE/dF, dE/dO and the counted pairs.
template <int STRIDE>
__global__ void forwardKernel(std::size_t s, const float* x /* [S,3] */, const float* fStatic /* [S,STRIDE] */,
                              const float* oStatic /* [S] */, const std::uint32_t* offsets /* [S+1] */,
                              const std::uint32_t* items /* [P] */, const PreparedGaussian* kernels /* [G] */,
                              const float* params /* [G,PER_G] */, const float* targetF /* [S,STRIDE] */,
                              const float* targetO /* [S] */, float cutoff, float lambda1, float lambda2,
                              float* gF /* [S,STRIDE] */, float* gO /* [S] */, float* energy /* [S,3] */,
                              std::uint32_t* pairCount /* [S] */, float* featuresOut /* [S,STRIDE] or null */,
                              float* opacityOut /* [S] or null */)
{
    constexpr int perG = 11 + STRIDE;
    const std::size_t j = std::size_t(blockIdx.x) * blockDim.x + threadIdx.x;
    if (j >= s) return;
    float f[STRIDE];
#pragma unroll
    for (int c = 0; c < STRIDE; ++c) f[c] = fStatic[j * STRIDE + c];
    float o = oStatic[j];
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
    float g[STRIDE], terms[3], go;
    sampleLoss<float, float>(f, targetF + j * STRIDE, o, targetO[j], STRIDE, lambda1, lambda2, g, go, terms);
#pragma unroll
    for (int c = 0; c < STRIDE; ++c) gF[j * STRIDE + c] = g[c];
    gO[j] = go;
    for (int t = 0; t < 3; ++t) energy[3 * j + t] = terms[t];
    if (featuresOut) {
#pragma unroll
        for (int c = 0; c < STRIDE; ++c) featuresOut[j * STRIDE + c] = f[c];
        opacityOut[j] = o;
    }
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
    for (std::size_t j = std::size_t(blockIdx.x) * blockDim.x + threadIdx.x; j < s; j += std::size_t(gridDim.x) * blockDim.x) {
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

/// Gradient of each moving Gaussian: one warp gathers its pairs from the Gaussian-major list
/// (lanes stride over the pairs, double accumulators, butterfly sums): no atomics.
template <int STRIDE>
__global__ void backwardKernel(std::size_t g, const std::uint32_t* offsets /* [G+1] */, const std::uint32_t* items /* [P] */,
                               const float* x /* [S,3] */, const PreparedGaussian* kernels /* [G] */,
                               const float* params /* [G,PER_G] */, const float* gF /* [S,STRIDE] */,
                               const float* gO /* [S] */, float cutoff, float* grad /* [G,PER_G] */)
{
    constexpr int perG = 11 + STRIDE;
    const std::size_t k = (std::size_t(blockIdx.x) * blockDim.x + threadIdx.x) / kWarp;
    const int lane = int(threadIdx.x) % kWarp;
    if (k >= g) return; // whole warps leave together (blockDim is a multiple of the warp)
    const PreparedGaussian kg = kernels[k];
    const float* h = params + k * perG + kSh;
    GaussianAccum<double> acc;
    double gh[STRIDE];
#pragma unroll
    for (int c = 0; c < STRIDE; ++c) gh[c] = 0;
    for (std::uint32_t e = offsets[k] + std::uint32_t(lane); e < offsets[k + 1]; e += kWarp) {
        const std::uint32_t j = items[e];
        const Vec3f xj(x[3 * std::size_t(j)], x[3 * std::size_t(j) + 1], x[3 * std::size_t(j) + 2]);
        Vec3f ad;
        const float w = kg.weight(xj - kg.mean, cutoff, &ad);
        if (w == 0.0f) continue;
        const float* gfj = gF + std::size_t(j) * STRIDE;
        double gw = gO[j];
#pragma unroll
        for (int c = 0; c < STRIDE; ++c) {
            const double gfc = double(gfj[c]);
            gw += gfc * double(h[c]);
            gh[c] += double(w) * gfc;
        }
        pairBackward<double>(gw, double(w), double(kg.alpha), Vec3d(ad), acc);
    }
    for (int a = 0; a < 3; ++a) acc.mean[a] = warpSum(acc.mean[a]);
    for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) acc.sigma.m[a][b] = warpSum(acc.sigma.m[a][b]);
    acc.alpha = warpSum(acc.alpha);
#pragma unroll
    for (int c = 0; c < STRIDE; ++c) gh[c] = warpSum(gh[c]);
    float* out = grad + k * perG;
#pragma unroll
    for (int c = 0; c < STRIDE; ++c)
        if (c % kWarp == lane) out[kSh + c] = float(gh[c]);
    if (lane != 0) return;
    const GaussianParamGrad<double> pg = paramBackward(unpackParams(params + k * perG), acc);
    for (int a = 0; a < 3; ++a) out[kMean + a] = float(pg.mean[a]);
    out[kRot] = float(pg.rotation.w);
    out[kRot + 1] = float(pg.rotation.x);
    out[kRot + 2] = float(pg.rotation.y);
    out[kRot + 3] = float(pg.rotation.z);
    for (int a = 0; a < 3; ++a) out[kLogScale + a] = float(pg.logScale[a]);
    out[kLogit] = float(pg.logit);
}

/// Learning rates of one step, per packed parameter group.
struct StepRates {
    float position, rotation, logScale, opacity, sh;
};

/// keepBest, step 1: compare the energy of `iteration` with the best so far (one thread, so no
/// race on `best`); flag = 1 when it is lower, and it becomes the best. Same comparison of the same
/// double sum as the CPU loop.
__global__ void bestFlagKernel(const EnergySum* sum, int iteration, double* best, int* bestIteration, int* flag)
{
    const double total = sum->color + sum->opacity + sum->boundary;
    const int better = total < *best ? 1 : 0;
    *flag = better;
    if (better) {
        *best = total;
        *bestIteration = iteration;
    }
}

/// keepBest, step 2: copy the parameters into the snapshot when the flag is set.
__global__ void snapshotKernel(std::size_t n, const int* flag, const float* params /* [G,PER_G] */,
                               float* snapshot /* [G,PER_G] */)
{
    const std::size_t i = blockIdx.x * std::size_t(blockDim.x) + threadIdx.x;
    if (i < n && *flag) snapshot[i] = params[i];
}

__global__ void initBestKernel(double* best, int* bestIteration)
{
    *best = CUDART_INF;
    *bestIteration = 0;
}

/// Adam on every packed parameter, operation for operation as stage2/Adam.h: the float moments
/// use round-to-nearest intrinsics so nvcc cannot contract them into FMAs (the CPU does not).
__global__ void adamKernel(std::size_t n, int perG, float* params /* [G,PER_G] */, const float* grad /* [G,PER_G] */,
                           float* m /* [G,PER_G] */, float* v /* [G,PER_G] */, float beta1, float beta2, float epsilon,
                           double corr1, double corr2, StepRates lr)
{
    const std::size_t i = std::size_t(blockIdx.x) * blockDim.x + threadIdx.x;
    if (i >= n) return;
    const int c = int(i % std::size_t(perG));
    const float rate = c < kRot ? lr.position
                                : (c < kLogScale ? lr.rotation : (c < kLogit ? lr.logScale : (c == kLogit ? lr.opacity : lr.sh)));
    const float g = grad[i];
    const float mi = __fadd_rn(__fmul_rn(beta1, m[i]), __fmul_rn(1.0f - beta1, g));
    const float vi = __fadd_rn(__fmul_rn(beta2, v[i]), __fmul_rn(__fmul_rn(1.0f - beta2, g), g));
    m[i] = mi;
    v[i] = vi;
    const double mHat = __ddiv_rn(double(mi), corr1), vHat = __ddiv_rn(double(vi), corr2);
    const double step = __ddiv_rn(__dmul_rn(double(rate), mHat), __dadd_rn(__dsqrt_rn(vHat), double(epsilon)));
    params[i] = __fsub_rn(params[i], float(step));
}

// ---------------------------------------------------------------------------------------------
// The solver: device state of one Stage II run.

class Solver {
public:
    Solver(const GaussianCloud& cloud, const SampleSet& samples, const std::vector<std::uint8_t>& moving,
           const std::vector<std::int32_t>& gaussianCell, const StageTwoOptions& options)
        : mOptions(options), mSetup(setupStageTwo(cloud, samples, moving, gaussianCell, options)),
          mStride(cloud.shStride()), mPerG(11 + cloud.shStride()), mS(mSetup.used.size()), mG(mSetup.moving.size()),
          mTimer(mStream.stream)
    {
        if (mStride > 48 || mStride % 3 != 0) throw InputError(msg("Stage II (CUDA): unsupported SH stride ", mStride));
        const cudaStream_t st = mStream.stream;
        // Gather what the loop needs for the used samples and the moving Gaussians, upload once.
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
            float* p = params.data() + k * std::size_t(mPerG);
            for (int a = 0; a < 3; ++a) p[kMean + a] = cloud.means[3 * i + std::size_t(a)];
            for (int a = 0; a < 4; ++a) p[kRot + a] = cloud.rotations[4 * i + std::size_t(a)];
            for (int a = 0; a < 3; ++a) p[kLogScale + a] = cloud.logScales[3 * i + std::size_t(a)];
            p[kLogit] = cloud.opacities[i];
            std::copy_n(cloud.shOf(i), mStride, p + kSh);
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
        mKernels.resize(mG);
        mBoxLo.resize(3 * mG);
        mBoxHi.resize(3 * mG);
        mGrad.resize(mG * std::size_t(mPerG));
        mAdamM.resize(mG * std::size_t(mPerG));
        mAdamV.resize(mG * std::size_t(mPerG));
        mGF.resize(mS * std::size_t(mStride));
        mGO.resize(mS);
        mEnergy.resize(3 * mS);
        mPairCount.resize(mS);
        mPartial.resize(kReduceBlocks);
        mSums.resize(std::size_t(std::max(options.iterations, 0)) + 1);
        if (mAdamM.size() > 0) {
            SPLATWARP_CUDA_CHECK(cudaMemsetAsync(mAdamM.data(), 0, mAdamM.bytes(), st));
            SPLATWARP_CUDA_CHECK(cudaMemsetAsync(mAdamV.data(), 0, mAdamV.bytes(), st));
        }
        // The uploads read host vectors that die with this constructor: wait for them.
        SPLATWARP_CUDA_CHECK(cudaStreamSynchronize(st));
    }

    const StageTwoSetup& setup() const { return mSetup; }
    int stride() const { return mStride; }
    cudaStream_t stream() const { return mStream.stream; }
    PhaseTimer& timer() { return mTimer; }

    void prepare()
    {
        launch("prepareKernel", prepareKernel, mG, stream(), mG, mPerG, (const float*)mParams.data(),
               (const double*)mFilter.data(), mOptions.cutoff, mKernels.data());
    }

    /// Coverage in deformed space (see stage2/Coverage.h): bins by sorting (cell key, box)
    /// entries, samples look up their cell, per-sample lists ascending; then the pairs sorted by
    /// Gaussian (stable, so each Gaussian's samples ascend). Reads back three counts.
    void rebuildCoverage(int iteration)
    {
        const cudaStream_t st = stream();
        const int steps = std::max(1, std::min(mOptions.rebuildEvery, mOptions.iterations - iteration));
        const double move = double(steps) * double(stageTwoPositionRate(mOptions, iteration, mSetup.sceneExtent));
        launch("boxKernel", boxKernel, mG, st, mG, mPerG, (const float*)mParams.data(), (const double*)mFilter.data(),
               steps, move, mOptions, mBoxLo.data(), mBoxHi.data());
        ++mRebuilds;
        if (mG == 0 || mS == 0) {
            clearPairs();
            return;
        }
        // Cell edge: half the mean box edge (the CPU uses half the median; any size gives the
        // same pairs), see BoxBins.
        if (!mBins.build(mG, (const float*)mBoxLo.data(), (const float*)mBoxHi.data(), st, "Stage II (CUDA) coverage")) {
            clearPairs();
            return;
        }
        const float inv = mBins.inv();
        const unsigned long long entries = mBins.entries();
        // Samples: count, scan, fill.
        mSampleCount.resize(mS + 1);
        launch("coverageKernel<count>", coverageKernel<false>, mS + 1, st, mS, (const float*)mX.data(), inv,
               mBins.keys(), mBins.boxes(),
               std::size_t(entries), (const float*)mBoxLo.data(), (const float*)mBoxHi.data(), mSampleCount.data(),
               (std::uint32_t*)nullptr, (std::uint32_t*)nullptr);
        cubCall([&](void* t, std::size_t& b) {
            return cub::DeviceScan::ExclusiveSum(t, b, mSampleCount.data(), mSampleCount.data(), mS + 1, st);
        });
        unsigned long long pairs = 0;
        SPLATWARP_CUDA_CHECK(cudaMemcpyAsync(&pairs, mSampleCount.data() + mS, sizeof(pairs), cudaMemcpyDeviceToHost, st));
        SPLATWARP_CUDA_CHECK(cudaStreamSynchronize(st));
        if (pairs > 0xffffffffull)
            throw InputError(msg("Stage II coverage has ", pairs, " pairs; too many for 32-bit indices"));
        mPairs = pairs;
        mSampleItems.resize(pairs);
        mPairSample.resize(pairs);
        mGaussianKeys.resize(pairs);
        mGaussianItems.resize(pairs);
        launch("coverageKernel<fill>", coverageKernel<true>, mS, st, mS, (const float*)mX.data(), inv,
               mBins.keys(), mBins.boxes(),
               std::size_t(entries), (const float*)mBoxLo.data(), (const float*)mBoxHi.data(), mSampleCount.data(),
               mSampleItems.data(), mPairSample.data());
        mSampleOffsets.resize(mS + 1);
        launch("narrowOffsetsKernel", narrowOffsetsKernel, mS + 1, st, mS + 1, (const unsigned long long*)mSampleCount.data(),
               mSampleOffsets.data());
        // Gaussian-major list: pairs (in sample order) sorted by box, stable.
        int bits = 1;
        while (bits < 32 && (std::size_t(1) << bits) < mG) ++bits;
        if (pairs > 0)
            cubCall([&](void* t, std::size_t& b) {
                return cub::DeviceRadixSort::SortPairs(t, b, (const std::uint32_t*)mSampleItems.data(), mGaussianKeys.data(),
                                                       (const std::uint32_t*)mPairSample.data(), mGaussianItems.data(),
                                                       pairs, 0, bits, st);
            });
        mGaussianOffsets.resize(mG + 1);
        launch("gaussianOffsetsKernel", gaussianOffsetsKernel, mG + 1, st, mG, (const std::uint32_t*)mGaussianKeys.data(),
               std::size_t(pairs), mGaussianOffsets.data());
    }

    /// Forward pass; the energy and pair count of `iteration` go to its slot on the device.
    void forward(int iteration, float* featuresOut = nullptr, float* opacityOut = nullptr)
    {
        dispatchStride([&](auto strideTag) {
            constexpr int kStride = decltype(strideTag)::value;
            launch("forwardKernel", forwardKernel<kStride>, mS, stream(), mS, (const float*)mX.data(),
                   (const float*)mFStatic.data(), (const float*)mOStatic.data(), (const std::uint32_t*)mSampleOffsets.data(),
                   (const std::uint32_t*)mSampleItems.data(), (const PreparedGaussian*)mKernels.data(),
                   (const float*)mParams.data(), (const float*)mTargetF.data(), (const float*)mTargetO.data(),
                   mOptions.cutoff, mOptions.lambdaOpacity, mOptions.boundaryWeight, mGF.data(), mGO.data(),
                   mEnergy.data(), mPairCount.data(), featuresOut, opacityOut);
        });
        energyPartialKernel<<<kReduceBlocks, kBlock, 0, stream()>>>(mS, mEnergy.data(), mPairCount.data(), mPartial.data());
        SPLATWARP_CUDA_CHECK_LAUNCH("energyPartialKernel");
        energyFinalKernel<<<1, kBlock, 0, stream()>>>(mPartial.data(), mSums.data() + iteration);
        SPLATWARP_CUDA_CHECK_LAUNCH("energyFinalKernel");
    }

    /// The energy of an iteration (waits for it).
    StageTwoEnergy energy(int iteration, std::uint64_t* pairs) const
    {
        EnergySum sum;
        SPLATWARP_CUDA_CHECK(cudaMemcpyAsync(&sum, mSums.data() + iteration, sizeof(sum), cudaMemcpyDeviceToHost, stream()));
        SPLATWARP_CUDA_CHECK(cudaStreamSynchronize(stream()));
        StageTwoEnergy e;
        e.iteration = iteration;
        e.color = sum.color;
        e.opacity = sum.opacity;
        e.boundary = sum.boundary;
        e.total = e.color + e.opacity + e.boundary;
        if (pairs) *pairs = sum.pairs;
        return e;
    }

    /// Counted pairs of iterations 0..n-1 (waits).
    std::vector<std::uint64_t> pairsPerIteration(int n) const
    {
        std::vector<EnergySum> sums(std::size_t(std::max(n, 0)));
        mSums.download(sums.data(), sums.size(), stream());
        std::vector<std::uint64_t> out;
        for (const EnergySum& s : sums) out.push_back(s.pairs);
        return out;
    }

    void backward()
    {
        dispatchStride([&](auto strideTag) {
            constexpr int kStride = decltype(strideTag)::value;
            launch("backwardKernel", backwardKernel<kStride>, mG * kWarp, stream(), mG,
                   (const std::uint32_t*)mGaussianOffsets.data(), (const std::uint32_t*)mGaussianItems.data(),
                   (const float*)mX.data(), (const PreparedGaussian*)mKernels.data(), (const float*)mParams.data(),
                   (const float*)mGF.data(), (const float*)mGO.data(), mOptions.cutoff, mGrad.data());
        });
    }

    void step(int iteration)
    {
        // Bias corrections and rates on the host, exactly as Adam::beginStep and the CPU loop.
        const double corr1 = 1.0 - std::pow(double(mOptions.beta1), iteration + 1);
        const double corr2 = 1.0 - std::pow(double(mOptions.beta2), iteration + 1);
        const StepRates lr{stageTwoPositionRate(mOptions, iteration, mSetup.sceneExtent), mOptions.lrRotation,
                           mOptions.lrLogScale, mOptions.lrOpacity, mOptions.lrSh};
        launch("adamKernel", adamKernel, mParams.size(), stream(), mParams.size(), mPerG, mParams.data(),
               (const float*)mGrad.data(), mAdamM.data(), mAdamV.data(), mOptions.beta1, mOptions.beta2,
               mOptions.epsilon, corr1, corr2, lr);
    }

    /// keepBest: start tracking (best = +inf).
    void initBest()
    {
        mBestParams.resize(mParams.size());
        mBest.resize(1);
        mBestIteration.resize(1);
        mBestFlag.resize(1);
        initBestKernel<<<1, 1, 0, stream()>>>(mBest.data(), mBestIteration.data());
        SPLATWARP_CUDA_CHECK_LAUNCH("initBestKernel");
    }
    /// keepBest: snapshot the parameters when the energy of `iteration` (forward() done) is the lowest.
    void trackBest(int iteration)
    {
        bestFlagKernel<<<1, 1, 0, stream()>>>(mSums.data() + iteration, iteration, mBest.data(), mBestIteration.data(),
                                              mBestFlag.data());
        SPLATWARP_CUDA_CHECK_LAUNCH("bestFlagKernel");
        launch("snapshotKernel", snapshotKernel, mParams.size(), stream(), mParams.size(),
               (const int*)mBestFlag.data(), (const float*)mParams.data(), mBestParams.data());
    }
    /// keepBest: put the best parameters back (waits for the best energy and iteration).
    void restoreBest(int& iteration, double& energy)
    {
        if (mParams.size() > 0)
            SPLATWARP_CUDA_CHECK(cudaMemcpyAsync(mParams.data(), mBestParams.data(), mParams.size() * sizeof(float),
                                                 cudaMemcpyDeviceToDevice, stream()));
        mBest.download(&energy, 1, stream());
        mBestIteration.download(&iteration, 1, stream());
    }

    /// Write the packed parameters into the moving Gaussians of a cloud (waits).
    void download(GaussianCloud& cloud) const
    {
        const std::vector<float> params = mParams.download(stream());
        for (std::size_t k = 0; k < mG; ++k) {
            const std::size_t i = mSetup.moving[k];
            const float* p = params.data() + k * std::size_t(mPerG);
            for (int a = 0; a < 3; ++a) cloud.means[3 * i + std::size_t(a)] = p[kMean + a];
            for (int a = 0; a < 4; ++a) cloud.rotations[4 * i + std::size_t(a)] = p[kRot + a];
            for (int a = 0; a < 3; ++a) cloud.logScales[3 * i + std::size_t(a)] = p[kLogScale + a];
            cloud.opacities[i] = p[kLogit];
            std::copy_n(p + kSh, mStride, cloud.shOf(i));
        }
    }

    std::uint64_t coveragePairs() const { return mPairs; }
    int rebuilds() const { return mRebuilds; }

    /// Fill a probe with the coverage and gradients (waits).
    void downloadProbe(StageTwoCudaProbe& p) const
    {
        const cudaStream_t st = stream();
        p.boxLo = mBoxLo.download(st);
        p.boxHi = mBoxHi.download(st);
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

    StageTwoOptions mOptions;
    StageTwoSetup mSetup;
    int mStride, mPerG;
    std::size_t mS, mG;
    StreamHolder mStream;
    PhaseTimer mTimer;
    std::uint64_t mPairs = 0;
    int mRebuilds = 0;

    DeviceBuffer<float> mX{"sample positions"}, mFStatic{"static features"}, mOStatic{"static opacity"},
        mTargetF{"target features"}, mTargetO{"target opacity"}, mParams{"Gaussian parameters"},
        mGrad{"parameter gradients"}, mAdamM{"Adam first moments"}, mAdamV{"Adam second moments"},
        mGF{"feature gradients"}, mGO{"opacity gradients"}, mEnergy{"per-sample energies"},
        mBoxLo{"coverage boxes"}, mBoxHi{"coverage boxes"};
    DeviceBuffer<double> mFilter{"low-pass filters"};
    DeviceBuffer<PreparedGaussian> mKernels{"prepared Gaussians"};
    BoxBins mBins;
    DeviceBuffer<unsigned long long> mSampleCount{"coverage counts"};
    DeviceBuffer<std::uint32_t>
        mSampleOffsets{"coverage offsets"}, mSampleItems{"coverage pairs"}, mPairSample{"coverage pair samples"},
        mGaussianKeys{"Gaussian-major pair keys"}, mGaussianItems{"Gaussian-major pairs"},
        mGaussianOffsets{"Gaussian-major offsets"}, mPairCount{"per-sample pair counts"};
    DeviceBuffer<EnergySum> mPartial{"energy partial sums"}, mSums{"energies per iteration"};
    DeviceBuffer<float> mBestParams{"best-iterate parameters"};
    DeviceBuffer<double> mBest{"best energy"};
    DeviceBuffer<int> mBestIteration{"best iteration"}, mBestFlag{"best flag"};
    DeviceBuffer<unsigned char> mCubTemp{"CUB temporary storage"};
};

} // namespace

StageTwoReport optimiseStageTwoCuda(GaussianCloud& cloud, const SampleSet& samples, const std::vector<std::uint8_t>& moving,
                                    const std::vector<std::int32_t>& gaussianCell, const StageTwoOptions& options,
                                    const std::function<void(int, const GaussianCloud&)>& onEval, int evalEvery)
{
    Stopwatch total, phase;
    resetDeviceBytesPeak(); // the peak of this run's buffers (the solver's and their growth)
    Solver solver(cloud, samples, moving, gaussianCell, options);
    StageTwoReport report;
    report.device = "cuda";
    const StageTwoSetup& setup = solver.setup();
    report.samplesUsed = setup.used.size();
    report.samplesSkipped = samples.sampleCount() - setup.used.size();
    report.sceneExtent = setup.sceneExtent;
    report.movingGaussians = setup.moving.size();
    report.msSetup = phase.ms();

    PhaseTimer& timer = solver.timer();
    std::unique_ptr<GaussianCloud> evalCloud; // onEval sees a copy: the caller's cloud changes only on success
    const int reportEvery = std::max(options.reportEvery, 1);
    if (options.keepBest) solver.initBest();
    for (int it = 0; it <= options.iterations; ++it) {
        timer.begin(PhaseTimer::Forward);
        solver.prepare();
        timer.end();
        if ((it < options.iterations && it % options.rebuildEvery == 0) || (it == 0 && options.iterations == 0)) {
            timer.begin(PhaseTimer::Coverage);
            solver.rebuildCoverage(it);
            timer.end();
        }
        timer.begin(PhaseTimer::Forward);
        solver.forward(it);
        if (options.keepBest) solver.trackBest(it);
        timer.end();
        if (it % reportEvery == 0 || it == options.iterations) {
            std::uint64_t pairs = 0;
            const StageTwoEnergy e = solver.energy(it, &pairs);
            report.energies.push_back(e);
            progress(msg("Stage II (CUDA) iteration ", it, ": energy ", e.total, " (colour ", e.color, ", opacity ",
                         e.opacity, ", boundary ", e.boundary, "), ", pairs, " pairs"));
        }
        if (it == options.iterations) break; // final energy only
        timer.begin(PhaseTimer::Backward);
        solver.backward();
        timer.end();
        timer.begin(PhaseTimer::Update);
        solver.step(it);
        timer.end();
        if (onEval && evalEvery > 0 && (it + 1) % evalEvery == 0) {
            if (!evalCloud) evalCloud = std::make_unique<GaussianCloud>(cloud);
            solver.download(*evalCloud);
            onEval(it + 1, *evalCloud);
        }
    }
    report.pairsPerIteration = solver.pairsPerIteration(options.iterations);
    report.coveragePairs = solver.coveragePairs();
    report.coverageRebuilds = solver.rebuilds();
    if (options.keepBest) {
        solver.restoreBest(report.bestIteration, report.bestEnergy);
        if (report.bestIteration != options.iterations)
            progress(msg("Stage II (CUDA): kept iteration ", report.bestIteration, " (lowest energy ", report.bestEnergy, ")"));
    } else {
        report.bestIteration = options.iterations;
        report.bestEnergy = report.energies.back().total;
    }
    solver.download(cloud);
    double ms[PhaseTimer::Count];
    timer.totals(ms);
    report.msCoverage = ms[PhaseTimer::Coverage];
    report.msForward = ms[PhaseTimer::Forward];
    report.msBackward = ms[PhaseTimer::Backward];
    report.msUpdate = ms[PhaseTimer::Update];
    report.msTotal = total.ms();
    report.gpuPeakBytes = deviceBytesPeak();
    return report;
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
    solver.rebuildCoverage(0);
    solver.forward(0, features.data(), opacity.data());
    solver.backward();
    p.energy = solver.energy(0, &p.pairs);
    p.features = features.download(solver.stream());
    p.opacity = opacity.download(solver.stream());
    solver.downloadProbe(p);
    return p;
}

} // namespace splatwarp::cuda
