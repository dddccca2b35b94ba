#include "stage2/CpuSolver.h"

#include <algorithm>
#include <cstring>

#include "core/Error.h"
#include "core/ParallelFor.h"
#include "core/Progress.h"
#include "stage2/BlockKernels.h"
#include "stage2/SampleBlocks.h"
#include "stage2/StageTwoCommon.h"
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

class CpuSolver final : public StageTwoSolver {
public:
    CpuSolver(const GaussianCloud& cloud, const SampleSet& samples, const std::vector<std::uint8_t>& moving,
              const std::vector<std::int32_t>& gaussianCell, const StageTwoOptions& options);

    const char* device() const override { return "cpu"; }
    void describe(StageTwoReport& r) const override;
    void prepare() override;
    void rebuildCoverage(int iteration) override;
    bool coverageHolds() override;
    std::uint64_t coveragePairs() const override { return mCoverage.pairCount(); }
    StageTwoEnergy forward(int iteration, std::uint64_t& pairs) override;
    void backward() override;
    void step(int iteration) override;
    void saveBest() override { mBest = mParams; }
    void restoreBest() override { mParams = mBest; }
    void writeTo(GaussianCloud& cloud) const override;
    StageTwoPhaseTimes times() const override { return mTimes; }

    /// Features per used sample of the last forward pass, for probes (off unless asked).
    void keepFeatures(std::vector<float>* f, std::vector<float>* o)
    {
        mFeaturesOut = f;
        mOpacityOut = o;
    }
    void probeInto(StageTwoProbe& p) const;

private:
    const float* row(std::size_t k) const { return mParams.data() + k * std::size_t(mPerG); }
    std::uint64_t forwardBlock(std::size_t b);
    void backwardPairs(std::size_t b, const BlockPoints& pts);
    void backwardGaussian(std::size_t k);
    std::size_t partialStride() const { return kPartial + std::size_t(mStride); }

    /// Backward sums kept per (block, Gaussian) pair before the SH ones: mean 3, sigma 6, alpha.
    static constexpr std::size_t kPartial = 10;

    const SampleSet& mSamples;
    StageTwoOptions mOptions;
    StageTwoSetup mSetup;
    int mStride, mPerG;
    std::size_t mS, mG;
    double mSetupMs = 0;
    SampleBlocks mBlocks;
    BlockCoverage mCoverage;
    std::vector<float> mParams, mBest, mGrad, mAdamM, mAdamV; // [G, PER_G]
    std::vector<PreparedGaussian> mKernels;                  // [G]
    std::vector<float> mBoxLo, mBoxHi;                        // [G,3]
    std::vector<CoverageSlabs> mSlabs;                        // [G] coverage slabs (the reach until the next rebuild)
    std::vector<CoverageSlabs> mNowSlabs;                     // [G] slabs of the Gaussians as they are now (chunk culling)
    std::vector<std::uint8_t> mHolds;                         // [G]
    std::vector<float> mGF, mGO;      // per padded slot: [P*stride] ([stride][lanes] per block), [P]
    std::vector<float> mEnergy;       // [S,3]
    std::vector<std::uint64_t> mBlockPairs; // [B] counted pairs of the last forward pass
    std::vector<std::uint64_t> mPairMask;   // [block-major coverage entries] counting lanes of the last forward pass
    std::vector<float> mPartials;           // [block-major coverage entries, kPartial + stride] backward sums of each pair
    std::vector<float>*mFeaturesOut = nullptr, *mOpacityOut = nullptr;
    StageTwoPhaseTimes mTimes;
};

CpuSolver::CpuSolver(const GaussianCloud& cloud, const SampleSet& samples, const std::vector<std::uint8_t>& moving,
                     const std::vector<std::int32_t>& gaussianCell, const StageTwoOptions& options)
    : mSamples(samples), mOptions(options)
{
    Stopwatch watch;
    mSetup = setupStageTwo(cloud, samples, moving, gaussianCell, options);
    mStride = cloud.shStride();
    if (mStride > kMaxShStride) throw InputError(msg("Stage II: unsupported SH stride ", mStride));
    mPerG = packedParamCount(mStride);
    mS = mSetup.used.size();
    mG = mSetup.moving.size();
    std::vector<std::int32_t> cells(mS);
    for (std::size_t j = 0; j < mS; ++j) cells[j] = samples.sampleCell[mSetup.used[j]];
    mBlocks = SampleBlocks::build(mSetup.x.data(), cells.data(), mS);
    const std::size_t n = mG * std::size_t(mPerG);
    mParams.resize(n);
    for (std::size_t k = 0; k < mG; ++k) packGaussian(cloud, mSetup.moving[k], mParams.data() + k * std::size_t(mPerG));
    mGrad.assign(n, 0.0f);
    mAdamM.assign(n, 0.0f);
    mAdamV.assign(n, 0.0f);
    mKernels.resize(mG);
    mBoxLo.resize(3 * mG);
    mBoxHi.resize(3 * mG);
    mSlabs.resize(mG);
    mNowSlabs.resize(mG);
    mHolds.resize(mG);
    mGF.assign(mBlocks.slots() * std::size_t(mStride), 0.0f); // padding slots stay 0: they add nothing
    mGO.assign(mBlocks.slots(), 0.0f);
    mEnergy.resize(3 * mS);
    mBlockPairs.resize(mBlocks.count());
    mSetupMs = watch.ms();
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
        mKernels[k] = PreparedGaussian::from(prepareParams(p, filter, double(mOptions.cutoff)));
        stageTwoCoverageSlabs(p, filter, 0, 0.0, mOptions, mNowSlabs[k]); // zero steps: the Gaussian as it is
    });
}

void CpuSolver::rebuildCoverage(int iteration)
{
    PhaseClock clock(mTimes.coverage);
    // Each box holds what `steps` Adam steps can reach (each step moves a parameter by about its
    // learning rate), plus a relative margin; see stageTwoReach().
    const int steps = std::max(1, std::min(mOptions.rebuildEvery, mOptions.iterations - iteration));
    const double move = double(steps) * double(stageTwoPositionRate(mOptions, iteration, mSetup.sceneExtent));
    parallelFor(mG, 256, mOptions.threaded, [&](std::size_t k) {
        const GaussianParams<double> p = unpackParams(row(k));
        const Mat3d& filter = mSetup.filter[mSetup.moving[k]];
        stageTwoCoverageBox(p, filter, steps, move, mOptions, &mBoxLo[3 * k], &mBoxHi[3 * k]);
        stageTwoCoverageSlabs(p, filter, steps, move, mOptions, mSlabs[k]);
    });
    mCoverage.build(mBlocks, mBoxLo.data(), mBoxHi.data(), mSlabs.data(), mG, mOptions.threaded);
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

std::uint64_t CpuSolver::forwardBlock(std::size_t b)
{
    const std::size_t stride = std::size_t(mStride), j0 = mBlocks.first[b], s0 = mBlocks.slot[b];
    const BlockPoints pts{&mBlocks.px[s0], &mBlocks.py[s0], &mBlocks.pz[s0], mBlocks.lanesOf(b), mBlocks.samplesOf(b),
                          &mBlocks.chunkLo[3 * (s0 / kSimdLanes)], &mBlocks.chunkHi[3 * (s0 / kSimdLanes)]};
    const std::size_t lanes = std::size_t(pts.lanes);
    alignas(32) float f[kMaxShStride * kMaxBlockSamples], o[kMaxBlockSamples], w[kMaxBlockSamples];
    for (std::size_t t = 0; t < lanes; ++t) {
        const bool real = t < std::size_t(pts.samples);
        o[t] = real ? mSetup.oStatic[j0 + t] : 0.0f;
        for (std::size_t c = 0; c < stride; ++c) f[c * lanes + t] = real ? mSetup.fStatic[(j0 + t) * stride + c] : 0.0f;
    }
    std::uint64_t pairs = 0;
    const auto& offsets = mCoverage.blockOffsets();
    const auto& items = mCoverage.blockItems();
    for (std::uint64_t e = offsets[b]; e < offsets[b + 1]; ++e) {
        const std::uint32_t k = items[e];
        const std::uint64_t mask = blockWeights(mKernels[k], pts, mOptions.cutoff, w, nullptr, nullptr, nullptr,
                                                ~std::uint64_t(0), &mNowSlabs[k]);
        mPairMask[e] = mask; // the backward pass evaluates only these lanes' chunks
        if (mask == 0) continue;
        pairs += std::uint64_t(__builtin_popcountll(mask));
        blockAccumulate(w, pts.lanes, mask, row(k) + kParamSh, mStride, f, o);
    }
    for (std::size_t t = 0; t < std::size_t(pts.samples); ++t) {
        const std::size_t j = j0 + t, sj = mSetup.used[j];
        float fj[kMaxShStride], gfj[kMaxShStride], terms[3];
        for (std::size_t c = 0; c < stride; ++c) fj[c] = f[c * lanes + t];
        sampleLoss<float, float>(fj, mSamples.targetF.data() + sj * stride, o[t], mSamples.targetO[sj], mStride,
                                 mOptions.lambdaOpacity, mOptions.boundaryWeight, gfj, mGO[s0 + t], terms);
        for (std::size_t c = 0; c < stride; ++c) mGF[s0 * stride + c * lanes + t] = gfj[c];
        for (int a = 0; a < 3; ++a) mEnergy[3 * j + std::size_t(a)] = terms[a];
        if (mFeaturesOut) std::copy(fj, fj + stride, mFeaturesOut->data() + j * stride);
        if (mOpacityOut) (*mOpacityOut)[j] = o[t];
    }
    backwardPairs(b, pts);
    return pairs;
}

/// The backward sums of each of the block's counting pairs, while its dE/dF, dE/dO and positions
/// are in cache (the per-Gaussian gather in backward() then only adds them up).
void CpuSolver::backwardPairs(std::size_t b, const BlockPoints& pts)
{
    const std::size_t stride = std::size_t(mStride), s0 = mBlocks.slot[b], ps = partialStride();
    alignas(32) float w[kMaxBlockSamples], ax[kMaxBlockSamples], ay[kMaxBlockSamples], az[kMaxBlockSamples];
    const auto& offsets = mCoverage.blockOffsets();
    const auto& items = mCoverage.blockItems();
    for (std::uint64_t e = offsets[b]; e < offsets[b + 1]; ++e) {
        const std::uint64_t mask = mPairMask[e];
        if (mask == 0) continue;
        const std::uint32_t k = items[e];
        const PreparedGaussian& kg = mKernels[k];
        blockWeights(kg, pts, mOptions.cutoff, w, ax, ay, az, chunksOf(mask));
        BlockPairSums sums;
        blockBackward(w, ax, ay, az, pts.lanes, mask, &mGF[s0 * stride], &mGO[s0], row(k) + kParamSh, mStride, kg.alpha, sums);
        float* out = mPartials.data() + e * ps;
        for (int a = 0; a < 3; ++a) out[a] = float(sums.mean[a]);
        for (int a = 0; a < 6; ++a) out[3 + a] = float(sums.sigma[a]);
        out[9] = float(sums.alpha);
        for (std::size_t c = 0; c < stride; ++c) out[kPartial + c] = float(sums.sh[c]);
    }
}

StageTwoEnergy CpuSolver::forward(int iteration, std::uint64_t& pairs)
{
    PhaseClock clock(mTimes.forward);
    if (mFeaturesOut) mFeaturesOut->assign(mS * std::size_t(mStride), 0.0f);
    if (mOpacityOut) mOpacityOut->assign(mS, 0.0f);
    mPairMask.resize(mCoverage.pairCount());
    mPartials.resize(mCoverage.pairCount() * partialStride());
    parallelFor(mBlocks.count(), 4, mOptions.threaded, [&](std::size_t b) { mBlockPairs[b] = forwardBlock(b); });
    // Serial sums in sample order: deterministic for any thread count.
    StageTwoEnergy e;
    e.iteration = iteration;
    for (std::size_t j = 0; j < mS; ++j) {
        e.color += mEnergy[3 * j];
        e.opacity += mEnergy[3 * j + 1];
        e.boundary += mEnergy[3 * j + 2];
    }
    e.total = e.color + e.opacity + e.boundary;
    pairs = 0;
    for (std::uint64_t p : mBlockPairs) pairs += p;
    return e;
}

void CpuSolver::backwardGaussian(std::size_t k)
{
    const std::size_t stride = std::size_t(mStride), ps = partialStride();
    double sums[kPartial + kMaxShStride] = {};
    const auto& offsets = mCoverage.gaussianOffsets();
    const auto& entryOf = mCoverage.blockEntryOf();
    for (std::uint64_t e = offsets[k]; e < offsets[k + 1]; ++e) { // blocks ascending: a fixed order
        const std::uint32_t be = entryOf[e];
        if (mPairMask[be] == 0) continue;
        const float* in = mPartials.data() + std::size_t(be) * ps;
        for (std::size_t c = 0; c < ps; ++c) sums[c] += double(in[c]);
    }
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

void CpuSolver::step(int iteration)
{
    PhaseClock clock(mTimes.update);
    const AdamStep adam = AdamStep::at(mOptions, iteration + 1);
    const StepRates rates{stageTwoPositionRate(mOptions, iteration, mSetup.sceneExtent), mOptions.lrRotation,
                          mOptions.lrLogScale, mOptions.lrOpacity, mOptions.lrSh};
    parallelFor(mG, 1024, mOptions.threaded, [&](std::size_t k) {
        const std::size_t base = k * std::size_t(mPerG);
        for (int c = 0; c < mPerG; ++c) {
            const std::size_t i = base + std::size_t(c);
            adam.update(mParams[i], mAdamM[i], mAdamV[i], mGrad[i], rates.of(c));
        }
    });
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
    const std::size_t stride = std::size_t(mStride);
    p.gradF.assign(mS * stride, 0.0f);
    p.gradO.assign(mS, 0.0f);
    for (std::size_t b = 0; b < mBlocks.count(); ++b)
        for (int t = 0; t < mBlocks.samplesOf(b); ++t) {
            const std::size_t j = mBlocks.first[b] + std::size_t(t), s0 = mBlocks.slot[b];
            const std::size_t lanes = std::size_t(mBlocks.lanesOf(b));
            p.gradO[j] = mGO[s0 + std::size_t(t)];
            for (std::size_t c = 0; c < stride; ++c) p.gradF[j * stride + c] = mGF[s0 * stride + c * lanes + std::size_t(t)];
        }
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
    solver.keepFeatures(&p.features, &p.opacity);
    solver.prepare();
    solver.rebuildCoverage(0);
    p.energy = solver.forward(0, p.pairs);
    solver.backward();
    solver.probeInto(p);
    return p;
}

} // namespace splatwarp
