#include "stage2/CpuSolver.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstring>
#include <numeric>
#include <optional>

#include "core/Error.h"
#include "core/Memory.h"
#include "core/ParallelFor.h"
#include "core/Progress.h"
#include "stage2/BlockLoops.h"
#include "stage2/SampleBlocks.h"
#include "stage2/Coverage.h"
#include "stage2/StageTwoSetup.h"
#include "stage2/StageTwoParams.h"

namespace splatwarp {
namespace {

/// Milliseconds added to a phase total when the scope ends.
class PhaseClock {
public:
    explicit PhaseClock(double& total) : mTotal(total) {}
    ~PhaseClock() { mTotal += mWatch.ms(); }

private:
    double& mTotal;
    Stopwatch mWatch;
};

/// Rows of `stride` floats per used sample (rowOf(j)) in the block layout: [stride][lanes] per
/// block, padding lanes 0. Every float is written once, blocks in parallel (first touches included).
template <typename RowOf>
BigVector<float> toSlots(const SampleBlocks& blocks, std::size_t stride, bool threaded, const RowOf& rowOf)
{
    BigVector<float> out;
    out.resize(blocks.slots() * stride);
    parallelFor(blocks.count(), 256, threaded, [&](std::size_t b) {
        const std::size_t lanes = std::size_t(blocks.lanesOf(b)), samples = std::size_t(blocks.samplesOf(b));
        float* dst = out.data() + std::size_t(blocks.slot[b]) * stride;
        for (std::size_t t = 0; t < samples; ++t) {
            const float* src = rowOf(blocks.first[b] + t);
            for (std::size_t c = 0; c < stride; ++c) dst[c * lanes + t] = src[c];
        }
        for (std::size_t c = 0; c < stride; ++c) std::fill(dst + c * lanes + samples, dst + (c + 1) * lanes, 0.0f);
    });
    return out;
}

class CpuSolver final : public StageTwoSolver {
public:
    CpuSolver(const GaussianCloud& cloud, const SampleSet& samples, const std::vector<std::uint8_t>& moving,
              const std::vector<std::int32_t>& gaussianCell, const StageTwoOptions& options);

    Device device() const override { return Device::Cpu; }
    void describe(StageTwoReport& r) const override;
    void prepare() override;
    void rebuildCoverage(int iteration, bool onlyEscaped) override;
    bool coverageHolds() override;
    std::uint64_t coveragePairs() const override { return mCoverage.pairCount(); }
    StageTwoEnergy forward(int iteration, std::uint64_t& pairs) override;
    void backward() override;
    double step(const StageTwoStep& s) override;
    void saveIterate() override
    {
        mKeptParams = mParams;
        mKeptM = mAdamM;
        mKeptV = mAdamV;
    }
    void restoreIterate() override
    {
        mParams = mKeptParams;
        mAdamM = mKeptM;
        mAdamV = mKeptV;
    }
    void writeTo(GaussianCloud& cloud) const override;
    StageTwoPhaseTimes times() const override { return mTimes; }

    /// F, O, dE/dF and dE/dO per used sample of the last forward pass into a probe (off unless asked).
    void keepSamples(StageTwoProbe* probe) { mProbe = probe; }
    void probeInto(StageTwoProbe& p) const;

private:
    const float* row(std::size_t k) const { return mParams.data() + k * std::size_t(mPerG); }
    BlockPoints pointsOf(std::size_t b) const;
    void evaluateStatic(const GaussianCloud& cloud, const std::vector<std::uint8_t>& moving);
    std::uint64_t forwardBlock(std::size_t b);
    void keepOutputs(std::size_t b, const float* f, const float* o, const float* gF, const float* gO);
    void backwardGaussian(std::size_t k);
    std::size_t partialStride() const { return kPartial + std::size_t(mStride); }
    /// The most coverage pairs of bytesEach that --max-memory leaves room for beside what the
    /// process holds now, and that room in words for the error.
    struct PairRoom {
        std::uint64_t limit;
        std::string text;
    };
    PairRoom pairRoom(double bytesEach) const
    {
        const MemoryRoom room = memoryRoom(mOptions.maxMemoryBytes);
        return {coveragePairLimit(mOptions.maxMemoryBytes, room.used, bytesEach), room.text()};
    }
    /// The most memory a coverage pair takes: its lists, its chunk mask and slot, and a row of
    /// partial sums where it counts (every pair of a model of giants does).
    double pairBytes() const
    {
        return double(kCoveragePairBytes + sizeof(std::uint8_t) + sizeof(std::uint32_t) + partialStride() * sizeof(float));
    }

    /// Backward sums kept per (block, Gaussian) pair before the SH ones (blockBackward()).
    static constexpr std::size_t kPartial = kPairSums;

    const SampleSet& mSamples;
    StageTwoOptions mOptions;
    StageTwoSetup mSetup;
    int mStride, mPerG;
    std::size_t mS, mG;
    double mSetupMs = 0;
    SampleBlocks mBlocks;
    BlockCoverage mCoverage;
    std::optional<PairRoom> mPairRoom; // pairRoom() at the first build
    std::vector<float> mParams, mGrad, mAdamM, mAdamV;      // [G, PER_G]
    std::vector<float> mKeptParams, mKeptM, mKeptV;       // saveIterate()
    std::vector<double> mRowDecrease;                         // [G] step(): each row's first-order decrease
    std::vector<PreparedGaussian> mPrepared;                  // [G]
    std::vector<ChunkBound> mBounds;                          // [G]
    std::vector<float> mBoxLo, mBoxHi;                        // [G,3]
    std::vector<CoverageSlabs> mSlabs;                        // [G] coverage slabs (the reach until the next rebuild)
    std::vector<std::uint8_t> mHolds;                         // [G]
    // Per padded slot, [stride][lanes] or [lanes] per block (padding 0): static F and O, targets.
    BigVector<float> mStaticF, mStaticO, mTargetF, mTargetO;
    std::vector<std::uint8_t> mStaticBlock; // [B] whether any static F or O of the block is not zero
    std::vector<double> mBlockEnergy; // [B,3] each block's loss terms summed in sample order
    std::vector<std::uint64_t> mBlockPairs; // [B] counted pairs of the last forward pass
    BigVector<std::uint8_t> mPairChunks; // [block-major coverage entries] counting chunks of the last forward pass
    BigVector<float> mPartials;          // [counting pairs of the last pass, kPartial + stride] their backward sums, packed
    BigVector<std::uint32_t> mPartialSlot; // [block-major coverage entries] a counting pair's row of mPartials
    std::atomic<std::uint64_t> mPartialsUsed{0}; // rows of mPartials the blocks of this pass have taken
    StageTwoProbe* mProbe = nullptr;
    StageTwoPhaseTimes mTimes;
    // Thread time of the fused pass's two halves (forwardBlock()), to split its wall time between
    // the forward and the backward phase.
    std::atomic<std::int64_t> mForwardNs{0}, mPairBackwardNs{0};
};

CpuSolver::CpuSolver(const GaussianCloud& cloud, const SampleSet& samples, const std::vector<std::uint8_t>& moving,
                     const std::vector<std::int32_t>& gaussianCell, const StageTwoOptions& options)
    : mSamples(samples), mOptions(options)
{
    Stopwatch watch;
    mSetup = setupStageTwo(cloud, samples, moving, gaussianCell, options, false);
    mStride = cloud.shStride();
    if (mStride > kMaxShStride) throw InputError(msg("Stage II: unsupported SH stride ", mStride));
    mPerG = packedParamCount(mStride);
    mS = mSetup.used.size();
    mG = mSetup.moving.size();
    std::vector<std::int32_t> cells(mS);
    for (std::size_t j = 0; j < mS; ++j) cells[j] = samples.sampleCell[mSetup.used[j]];
    mBlocks = SampleBlocks::build(mSetup.x.data(), cells.data(), mS, mOptions.threaded);
    mCoverage = BlockCoverage(mBlocks);
    const std::size_t n = mG * std::size_t(mPerG);
    mParams.resize(n);
    for (std::size_t k = 0; k < mG; ++k) packGaussian(cloud, mSetup.moving[k], mParams.data() + k * std::size_t(mPerG));
    mGrad.assign(n, 0.0f);
    mAdamM.assign(n, 0.0f);
    mAdamV.assign(n, 0.0f);
    mRowDecrease.resize(mG);
    mPrepared.resize(mG);
    mBounds.resize(mG);
    mBoxLo.resize(3 * mG);
    mBoxHi.resize(3 * mG);
    mSlabs.resize(mG);
    mHolds.resize(mG);
    const std::size_t stride = std::size_t(mStride);
    evaluateStatic(cloud, moving);
    mTargetF = toSlots(mBlocks, stride, mOptions.threaded, [&](std::size_t j) { return &samples.targetF[mSetup.used[j] * stride]; });
    mTargetO = toSlots(mBlocks, 1, mOptions.threaded, [&](std::size_t j) { return &samples.targetO[mSetup.used[j]]; });
    mBlockEnergy.assign(3 * mBlocks.count(), 0.0);
    mBlockPairs.resize(mBlocks.count());
    mSetupMs = watch.ms();
}

void CpuSolver::evaluateStatic(const GaussianCloud& cloud, const std::vector<std::uint8_t>& moving)
{
    // The static Gaussians' fixed F and O, straight into the block layout with the block engine:
    // listed, in ascending order, only for the blocks they reach (the coverage of a Gaussian that
    // takes no step), so the same sums as the per-sample evaluation (setupStageTwo) in far less
    // time (demo: 1,323 static Gaussians against 942,464 samples).
    const std::size_t n = cloud.size(), stride = std::size_t(mStride), nb = mBlocks.count();
    std::vector<PreparedGaussian> prepared(n);
    std::vector<ChunkBound> bounds(n);
    std::vector<float> lo(3 * n, 1.0f), hi(3 * n, 0.0f); // moving: empty boxes, never listed
    std::vector<CoverageSlabs> slabs(n);
    // Nothing checks a static Gaussian's coverage later (it never moves), so its margin is never
    // below the default's, whatever a test sets for the moving ones (a negative pad forces escapes).
    StageTwoOptions o = mOptions;
    o.coveragePad = std::max(o.coveragePad, StageTwoOptions().coveragePad);
    parallelFor(n, 1024, mOptions.threaded, [&](std::size_t i) {
        if (moving[i]) return;
        const GaussianParams<double> p = gaussianParamsOf(cloud, i);
        prepared[i] = PreparedGaussian::from(prepareParams(p, mSetup.filter[i], double(mOptions.cutoff)));
        bounds[i] = ChunkBound::of(prepared[i]);
        stageTwoCoverageBox(p, mSetup.filter[i], 0, 0.0, o, &lo[3 * i], &hi[3 * i]);
        stageTwoCoverageSlabs(p, mSetup.filter[i], 0, 0.0, o, slabs[i]);
    });
    BlockCoverage coverage(mBlocks);
    const PairRoom room = pairRoom(double(kCoveragePairBytes));
    if (!coverage.build(lo.data(), hi.data(), slabs.data(), n, mOptions.threaded, nullptr, room.limit))
        throw coverageTooLarge("Stage II (the Gaussians that stay)", room.limit, double(kCoveragePairBytes), room.text,
                               mOptions.memoryAdvice);
    resizeDiscarding(mStaticF, mBlocks.slots() * stride); // zeroed block by block below (first touches in parallel)
    resizeDiscarding(mStaticO, mBlocks.slots());
    mStaticBlock.assign(nb, 0);
    parallelFor(nb, 16, mOptions.threaded, [&](std::size_t b) {
        const std::size_t s0 = mBlocks.slot[b], lanes = std::size_t(mBlocks.lanesOf(b));
        float* f = &mStaticF[s0 * stride];
        float* o = &mStaticO[s0];
        std::fill(f, f + lanes * stride, 0.0f);
        std::fill(o, o + lanes, 0.0f);
        const std::uint64_t e0 = coverage.blockOffsets()[b];
        const BlockGaussians gs{coverage.blockItems().data() + e0, std::size_t(coverage.blockOffsets()[b + 1] - e0),
                                prepared.data(), bounds.data(), cloud.sh.data(), stride};
        if (gs.n == 0) return;
        mStaticBlock[b] = blockFeatures(gs, pointsOf(b), mOptions.cutoff, mStride, f, o) > 0;
    });
}

void CpuSolver::describe(StageTwoReport& r) const
{
    r.samplesUsed = mS;
    r.samplesSkipped = mSamples.sampleCount() - mS;
    r.sceneExtent = mSetup.sceneExtent;
    r.movingGaussians = mG;
    r.msSetup = mSetupMs;
}

void CpuSolver::prepare()
{
    PhaseClock clock(mTimes.forward);
    parallelFor(mG, 256, mOptions.threaded, [&](std::size_t k) {
        const GaussianParams<double> p = unpackParams(row(k));
        const Mat3d& filter = mSetup.filter[mSetup.moving[k]];
        mPrepared[k] = PreparedGaussian::from(prepareParams(p, filter, double(mOptions.cutoff)));
        mBounds[k] = ChunkBound::of(mPrepared[k]);
    });
}

void CpuSolver::rebuildCoverage(int iteration, bool onlyEscaped)
{
    PhaseClock clock(mTimes.coverage);
    // Each box holds what its Gaussian can reach in the next coverageReachSteps() Adam steps
    // (each step moves a parameter by about its learning rate), plus a relative margin; see
    // stageTwoReach(). After a failed holds check only the Gaussians that left theirs get new
    // ones (mHolds: coverageHolds() just ran); the many that stayed keep their lists.
    const int steps = coverageReachSteps(mOptions, iteration);
    const double move = double(steps) * double(stageTwoPositionRate(mOptions, iteration, mSetup.sceneExtent));
    const std::uint8_t* keep = onlyEscaped && mCoverage.pairCount() > 0 ? mHolds.data() : nullptr;
    parallelFor(mG, 256, mOptions.threaded, [&](std::size_t k) {
        if (keep && keep[k]) return;
        const GaussianParams<double> p = unpackParams(row(k));
        const Mat3d& filter = mSetup.filter[mSetup.moving[k]];
        stageTwoCoverageBox(p, filter, steps, move, mOptions, &mBoxLo[3 * k], &mBoxHi[3 * k]);
        stageTwoCoverageSlabs(p, filter, steps, move, mOptions, mSlabs[k]);
    });
    if (!mPairRoom) mPairRoom = pairRoom(pairBytes()); // before any coverage is held (at a rebuild, the one it replaces is)
    if (!mCoverage.build(mBoxLo.data(), mBoxHi.data(), mSlabs.data(), mG, mOptions.threaded, keep, mPairRoom->limit))
        throw coverageTooLarge("Stage II", mPairRoom->limit, pairBytes(), mPairRoom->text, mOptions.memoryAdvice);
    // A rebuild frees and allocates on both threads' malloc arenas; the free fragments stayed
    // resident and Stage II's memory grew over its iterations (lastchance bend, 35 rebuilds: 858 MB
    // at iteration 10, 982 MB at 50; with this 788 and 793 MB).
    releaseFreedMemory();
}

bool CpuSolver::coverageHolds()
{
    PhaseClock clock(mTimes.coverage);
    parallelFor(mG, 256, mOptions.threaded, [&](std::size_t k) {
        mHolds[k] = stageTwoCoverageHolds(unpackParams(row(k)), mSetup.filter[mSetup.moving[k]], double(mOptions.cutoff),
                                          &mBoxLo[3 * k], &mBoxHi[3 * k], mSlabs[k]);
    });
    return std::all_of(mHolds.begin(), mHolds.end(), [](std::uint8_t h) { return h != 0; });
}

BlockPoints CpuSolver::pointsOf(std::size_t b) const
{
    const std::size_t s0 = mBlocks.slot[b];
    return BlockPoints{&mBlocks.px[s0], &mBlocks.py[s0], &mBlocks.pz[s0], mBlocks.lanesOf(b), mBlocks.samplesOf(b),
                       mBlocks.chunksOf(b)};
}

/// One block: its F and O (each listed Gaussian's counting lanes), the loss per sample, then the
/// backward sums of its pairs from the weights the forward kept (still in cache).
std::uint64_t CpuSolver::forwardBlock(std::size_t b)
{
    const std::size_t stride = std::size_t(mStride), s0 = mBlocks.slot[b];
    const BlockPoints pts = pointsOf(b);
    const std::size_t lanes = std::size_t(pts.lanes);
    // F, O, dE/dF, dE/dO of the block stay here, in cache, from the forward sums to the backward ones.
    alignas(32) float f[kMaxShStride * kMaxBlockSamples], o[kMaxBlockSamples], terms[3 * kMaxBlockSamples];
    alignas(32) float gF[kMaxShStride * kMaxBlockSamples], gO[kMaxBlockSamples];
    if (mStaticBlock[b]) {
        std::memcpy(f, &mStaticF[s0 * stride], lanes * stride * sizeof(float));
        std::memcpy(o, &mStaticO[s0], lanes * sizeof(float));
    } else { // most blocks: no static Gaussian reaches them, nothing to read
        std::memset(f, 0, lanes * stride * sizeof(float));
        std::memset(o, 0, lanes * sizeof(float));
    }
    const std::uint64_t e0 = mCoverage.blockOffsets()[b];
    const BlockGaussians gs{mCoverage.blockItems().data() + e0, std::size_t(mCoverage.blockOffsets()[b + 1] - e0),
                            mPrepared.data(), mBounds.data(), mParams.data() + kParamSh, std::size_t(mPerG)};
    // Per thread, reused: the kept chunks of the block's pairs and where each pair's start.
    thread_local std::vector<float> kept;
    thread_local std::vector<std::uint32_t> keptAt;
    const std::size_t room = gs.n * (lanes / kSimdLanes) * kKeptChunkFloats;
    if (kept.size() < room) kept.resize(room);
    if (keptAt.size() < gs.n) keptAt.resize(gs.n);
    const auto t0 = std::chrono::steady_clock::now();
    const std::uint64_t pairs =
        blockForward(gs, pts, mOptions.cutoff, mStride, f, o, mPairChunks.data() + e0, kept.data(), keptAt.data());
    blockLoss(f, o, &mTargetF[s0 * stride], &mTargetO[s0], pts.lanes, pts.samples, mStride, mOptions.lambdaOpacity,
              mOptions.boundaryWeight, gF, gO, terms);
    for (int a = 0; a < 3; ++a) {
        double sum = 0;
        for (std::size_t t = 0; t < std::size_t(pts.samples); ++t) sum += double(terms[std::size_t(a) * lanes + t]);
        mBlockEnergy[3 * b + std::size_t(a)] = sum;
    }
    if (mProbe) keepOutputs(b, f, o, gF, gO);
    const auto t1 = std::chrono::steady_clock::now();
    const std::uint8_t* chunks = mPairChunks.data() + e0;
    const std::size_t counting = gs.n - std::size_t(std::count(chunks, chunks + gs.n, std::uint8_t(0)));
    const std::uint64_t first = mPartialsUsed.fetch_add(counting, std::memory_order_relaxed); // rows in any order: the gather reads by slot
    blockBackward(gs, pts.lanes, chunks, kept.data(), keptAt.data(), gF, gO, mStride, mPartials.data() + first * partialStride(),
                  std::uint32_t(first), mPartialSlot.data() + e0);
    const auto t2 = std::chrono::steady_clock::now();
    mForwardNs += std::chrono::duration_cast<std::chrono::nanoseconds>(t1 - t0).count();
    mPairBackwardNs += std::chrono::duration_cast<std::chrono::nanoseconds>(t2 - t1).count();
    return pairs;
}

/// F, O, dE/dF and dE/dO of a block's samples for probes.
void CpuSolver::keepOutputs(std::size_t b, const float* f, const float* o, const float* gF, const float* gO)
{
    const std::size_t stride = std::size_t(mStride), lanes = std::size_t(mBlocks.lanesOf(b));
    for (std::size_t t = 0; t < std::size_t(mBlocks.samplesOf(b)); ++t) {
        const std::size_t j = mBlocks.first[b] + t;
        for (std::size_t c = 0; c < stride; ++c) {
            mProbe->features[j * stride + c] = f[c * lanes + t];
            mProbe->gradF[j * stride + c] = gF[c * lanes + t];
        }
        mProbe->opacity[j] = o[t];
        mProbe->gradO[j] = gO[t];
    }
}

StageTwoEnergy CpuSolver::forward(int iteration, std::uint64_t& pairs)
{
    const Stopwatch wall;
    mForwardNs = 0;
    mPairBackwardNs = 0;
    if (mProbe) {
        mProbe->features.assign(mS * std::size_t(mStride), 0.0f);
        mProbe->gradF.assign(mS * std::size_t(mStride), 0.0f);
        mProbe->opacity.assign(mS, 0.0f);
        mProbe->gradO.assign(mS, 0.0f);
    }
    resizeDiscarding(mPairChunks, mCoverage.pairCount()); // rewritten by every pass
    // At most every listed pair counts; the rows are taken from the front, so only the counting
    // pairs' pages are ever touched (guitar decoded twist: peak 0.94 -> 0.81 GB against a row per
    // listed pair).
    resizeDiscarding(mPartials, mCoverage.pairCount() * partialStride());
    resizeDiscarding(mPartialSlot, mCoverage.pairCount());
    mPartialsUsed = 0;
    parallelFor(mBlocks.count(), 4, mOptions.threaded, [&](std::size_t b) { mBlockPairs[b] = forwardBlock(b); });
    StageTwoEnergy e;
    e.iteration = iteration;
    for (std::size_t b = 0; b < mBlocks.count(); ++b) { // blocks in order: deterministic for any thread count
        e.color += mBlockEnergy[3 * b];
        e.opacity += mBlockEnergy[3 * b + 1];
        e.boundary += mBlockEnergy[3 * b + 2];
    }
    e.total = e.color + e.opacity + e.boundary;
    pairs = 0;
    for (std::uint64_t p : mBlockPairs) pairs += p;
    // The pass sums each block's forward and, while the block is in cache, its pairs' backward
    // sums: its wall time is shared out by the thread time of the two halves.
    const double ms = wall.ms(), f = double(mForwardNs), b = double(mPairBackwardNs);
    const double backwardShare = f + b > 0 ? b / (f + b) : 0.0;
    mTimes.forward += ms * (1.0 - backwardShare);
    mTimes.backward += ms * backwardShare;
    return e;
}

void CpuSolver::backwardGaussian(std::size_t k)
{
    const std::size_t stride = std::size_t(mStride), ps = partialStride();
    double sums[kPartial + kMaxShStride] = {};
    const auto& offsets = mCoverage.gaussianOffsets();
    // Its pairs' sums in block order (the entries ascend): a fixed order for any thread count.
    gatherPartials(mPartials.data(), ps, mPartialSlot.data(), mCoverage.blockEntryOf().data() + offsets[k],
                   std::size_t(offsets[k + 1] - offsets[k]), mPairChunks.data(), sums);
    GaussianAccum<double> acc;
    acc.mean = Vec3d(sums[0], sums[1], sums[2]);
    const int upper[3][3] = {{0, 1, 2}, {1, 3, 4}, {2, 4, 5}};
    for (int a = 0; a < 3; ++a)
        for (int c = 0; c < 3; ++c) acc.sigma.m[a][c] = sums[3 + upper[a][c]];
    acc.alpha = sums[9];
    float* out = mGrad.data() + k * std::size_t(mPerG);
    packGradient(paramBackward(unpackParams(row(k)), acc), out);
    for (std::size_t c = 0; c < stride; ++c) out[kParamSh + c] = float(sums[kPartial + c]);
}

void CpuSolver::backward()
{
    PhaseClock clock(mTimes.backward);
    parallelFor(mG, 8, mOptions.threaded, [&](std::size_t k) { backwardGaussian(k); });
}

double CpuSolver::step(const StageTwoStep& s)
{
    PhaseClock clock(mTimes.update);
    const AdamStep adam = AdamStep::at(mOptions, s.adamStep);
    const StepRates rates = StepRates::forStep(mOptions, s, mSetup.sceneExtent);
    parallelFor(mG, 1024, mOptions.threaded, [&](std::size_t k) {
        const std::size_t i = k * std::size_t(mPerG);
        mRowDecrease[k] = adamStepRow(adam, rates, mSetup.filter[mSetup.moving[k]], mOptions.maxMeanStep, mPerG,
                                      &mParams[i], &mAdamM[i], &mAdamV[i], &mGrad[i]);
    });
    return std::accumulate(mRowDecrease.begin(), mRowDecrease.end(), 0.0); // in row order, as the GPU's
}

void CpuSolver::writeTo(GaussianCloud& cloud) const
{
    for (std::size_t k = 0; k < mG; ++k) unpackGaussian(row(k), cloud, mSetup.moving[k]);
}

void CpuSolver::probeInto(StageTwoProbe& p) const
{
    p.used = mSetup.used;
    p.moving = mSetup.moving;
    p.grad = mGrad;
}

} // namespace

std::unique_ptr<StageTwoSolver> makeCpuStageTwoSolver(const GaussianCloud& cloud, const SampleSet& samples,
                                                      const std::vector<std::uint8_t>& moving,
                                                      const std::vector<std::int32_t>& gaussianCell,
                                                      const StageTwoOptions& options)
{
    return std::make_unique<CpuSolver>(cloud, samples, moving, gaussianCell, options);
}

StageTwoProbe probeCpuStageTwo(const GaussianCloud& cloud, const SampleSet& samples, const std::vector<std::uint8_t>& moving,
                               const std::vector<std::int32_t>& gaussianCell, const StageTwoOptions& options)
{
    StageTwoOptions o = options;
    o.iterations = std::max(o.iterations, 1); // the coverage boxes of a run that takes steps
    CpuSolver solver(cloud, samples, moving, gaussianCell, o);
    StageTwoProbe p;
    solver.keepSamples(&p);
    solver.prepare();
    solver.rebuildCoverage(0, false);
    p.energy = solver.forward(0, p.pairs);
    solver.backward();
    solver.probeInto(p);
    return p;
}

} // namespace splatwarp
