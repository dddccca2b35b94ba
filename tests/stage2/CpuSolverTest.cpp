// The CPU Stage II solver against a naive double-precision evaluator over every (sample,
// Gaussian) pair (no coverage, no blocks, no vectorisation), and the block structures it uses.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

#include "stage2/BlockLoops.h"
#include "stage2/CpuSolver.h"
#include "stage2/SampleBlocks.h"
#include "stage2/Coverage.h"
#include "stage2/StageTwoSetup.h"
#include "stage2/StageTwoDevice.h"
#include "stage2/StageTwoParams.h"
#include "stage2/StageTwoTestProblem.h"

using namespace splatwarp;
using namespace splatwarp::test;

namespace {

// Measured worst values over degrees 0-3 and block sizes 2^3, 3^3, 4^3 (float weights with
// fastExp and float per-lane partial sums against double throughout): features 1.0e-7,
// gradients 1.1e-7 (per Gaussian 3.5e-7). Tolerances: about twice those.
constexpr double kFeatureRel = 2e-7;
constexpr double kGradRel = 2.5e-7;
constexpr double kGradRelPerGaussian = 7e-7;

using Problem = RigidStageTwoProblem;

/// Random cloud, targets from the cloud moved rigidly on a lattice of n^3-sample cells; every
/// third Gaussian static.
Problem makeProblem(int degree, int n, std::uint32_t seed)
{
    Problem p;
    p.start = randomCloud(50, degree, seed, 0.45f, 0.04f, 0.12f);
    const GaussianCloud target = rigidlyMoved(p.start, quatToMatrix(Quatd{1.0, 0.04, -0.06, 0.05}), Vec3d(0.03, 0.02, -0.04));
    p.samples = latticeSampleSet(target, 10, 0.9f, n, p.options);
    p.moving.assign(p.start.size(), 1);
    for (std::size_t i = 0; i < p.moving.size(); i += 3) p.moving[i] = 0;
    p.cells = latticeCells(p.start, 10, 0.9f);
    return p;
}

/// Every Gaussian in double, prepared as Stage II does (same filters).
std::vector<BasicPreparedGaussian<double>> doublePrepared(const Problem& p, const StageTwoSetup& st)
{
    std::vector<BasicPreparedGaussian<double>> out(p.start.size());
    for (std::size_t i = 0; i < out.size(); ++i)
        out[i] = prepareParams(gaussianParamsOf(p.start, i), st.filter[i], double(p.options.cutoff));
    return out;
}

/// F, O at the used samples: every pair, double.
void referenceFeatures(const Problem& p, const StageTwoSetup& st, std::vector<double>& f, std::vector<double>& o)
{
    const auto prepared = doublePrepared(p, st);
    const std::size_t stride = std::size_t(p.start.shStride()), s = st.used.size();
    f.assign(s * stride, 0.0);
    o.assign(s, 0.0);
    for (std::size_t j = 0; j < s; ++j) {
        const Vec3d x(st.x[3 * j], st.x[3 * j + 1], st.x[3 * j + 2]);
        for (std::size_t i = 0; i < prepared.size(); ++i) {
            const double w = prepared[i].weight(x - prepared[i].mean, double(p.options.cutoff));
            o[j] += w;
            for (std::size_t c = 0; c < stride; ++c) f[j * stride + c] += w * double(p.start.shOf(i)[c]);
        }
    }
}

/// Packed parameter gradients from the solver's own dE/dF, dE/dO: every pair, double.
std::vector<double> referenceGradients(const Problem& p, const StageTwoSetup& st, const StageTwoProbe& probe)
{
    const auto prepared = doublePrepared(p, st);
    const std::size_t stride = std::size_t(p.start.shStride()), perG = std::size_t(packedParamCount(int(stride)));
    std::vector<double> out(probe.moving.size() * perG, 0.0);
    for (std::size_t k = 0; k < probe.moving.size(); ++k) {
        const std::size_t i = probe.moving[k];
        GaussianAccum<double> acc;
        double* row = out.data() + k * perG;
        for (std::size_t j = 0; j < st.used.size(); ++j) {
            const Vec3d x(st.x[3 * j], st.x[3 * j + 1], st.x[3 * j + 2]);
            Vec3d ad;
            const double w = prepared[i].weight(x - prepared[i].mean, double(p.options.cutoff), &ad);
            if (w == 0.0) continue;
            double gw = probe.gradO[j];
            for (std::size_t c = 0; c < stride; ++c) {
                gw += double(probe.gradF[j * stride + c]) * double(p.start.shOf(i)[c]);
                row[kParamSh + c] += w * double(probe.gradF[j * stride + c]);
            }
            pairBackward<double>(gw, w, prepared[i].alpha, ad, acc);
        }
        const GaussianParamGrad<double> g = paramBackward(gaussianParamsOf(p.start, i), acc);
        for (int a = 0; a < 3; ++a) row[kParamMean + a] = g.mean[a];
        row[kParamRotation] = g.rotation.w, row[kParamRotation + 1] = g.rotation.x;
        row[kParamRotation + 2] = g.rotation.y, row[kParamRotation + 3] = g.rotation.z;
        for (int a = 0; a < 3; ++a) row[kParamLogScale + a] = g.logScale[a];
        row[kParamLogit] = g.logit;
    }
    return out;
}

/// The blocks of `cells` cells of `per` samples each, scattered spread(c) about random centres in [-1, 1]^3.
template <typename Spread>
SampleBlocks randomCellBlocks(std::mt19937& rng, int cells, int per, const Spread& spread)
{
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    std::vector<float> x;
    std::vector<std::int32_t> cell;
    for (int c = 0; c < cells; ++c) {
        const float r = spread(c), cx = u(rng), cy = u(rng), cz = u(rng);
        for (int s = 0; s < per; ++s) {
            x.insert(x.end(), {cx + r * u(rng), cy + r * u(rng), cz + r * u(rng)});
            cell.push_back(c);
        }
    }
    return SampleBlocks::build(x.data(), cell.data(), cell.size());
}

} // namespace

TEST(CpuSolver, StaticContributionInBlocksIsThePerSampleOne)
{
    // The solver evaluates the static Gaussians in its blocks; setupStageTwo() per sample. Same
    // pairs, same ascending order: the same bits. Every Gaussian static, so F and O are theirs alone;
    // a negative coverage pad (which tests use to force escapes of moving ones) must not shrink them.
    for (int degree : {0, 2}) {
        Problem p = makeProblem(degree, 3, 300u + std::uint32_t(degree));
        p.moving.assign(p.start.size(), 0);
        if (degree == 2) p.options.coveragePad = -0.5f;
        const StageTwoSetup st = setupStageTwo(p.start, p.samples, p.moving, p.cells, p.options);
        const StageTwoProbe probe = probeCpuStageTwo(p.start, p.samples, p.moving, p.cells, p.options);
        ASSERT_EQ(probe.used, st.used);
        ASSERT_EQ(probe.features.size(), st.fStatic.size());
        EXPECT_GT(std::count_if(st.oStatic.begin(), st.oStatic.end(), [](float v) { return v > 0.0f; }), 100);
        EXPECT_EQ(probe.features, st.fStatic);
        EXPECT_EQ(probe.opacity, st.oStatic);
    }
}

TEST(CpuSolver, ProbeMatchesDoubleReference)
{
    for (int n : {2, 3, 4})
        for (int degree = 0; degree <= 3; ++degree) {
            const Problem p = makeProblem(degree, n, 100u + std::uint32_t(degree));
            const StageTwoSetup st = setupStageTwo(p.start, p.samples, p.moving, p.cells, p.options);
            const StageTwoProbe probe = probeCpuStageTwo(p.start, p.samples, p.moving, p.cells, p.options);
            ASSERT_EQ(probe.used, st.used);
            std::vector<double> f, o;
            referenceFeatures(p, st, f, o);
            const double ef = relativeError(probe.features, f), eo = relativeError(probe.opacity, o);
            const std::vector<double> g = referenceGradients(p, st, probe);
            const double eg = relativeError(probe.grad, g);
            const std::size_t perG = std::size_t(packedParamCount(p.start.shStride()));
            double worstPerGaussian = 0;
            for (std::size_t k = 0; k < probe.moving.size(); ++k) {
                const std::vector<float> a(probe.grad.begin() + std::ptrdiff_t(k * perG),
                                           probe.grad.begin() + std::ptrdiff_t((k + 1) * perG));
                const std::vector<double> b(g.begin() + std::ptrdiff_t(k * perG), g.begin() + std::ptrdiff_t((k + 1) * perG));
                worstPerGaussian = std::max(worstPerGaussian, relativeError(a, b));
            }
            std::printf("  n=%d degree %d: features %.3g opacity %.3g gradients %.3g (worst Gaussian %.3g), %llu pairs\n", n,
                        degree, ef, eo, eg, worstPerGaussian, (unsigned long long)probe.pairs);
            EXPECT_GT(probe.pairs, 0u);
            EXPECT_LT(ef, kFeatureRel);
            EXPECT_LT(eo, kFeatureRel);
            EXPECT_LT(eg, kGradRel);
            EXPECT_LT(worstPerGaussian, kGradRelPerGaussian);
        }
}

TEST(SampleBlocks, RunsOfOneCellPaddedToLanes)
{
    // Cells 5 (3 samples), 7 (70 samples: split at kMaxBlockSamples), 5 again (1 sample).
    std::vector<std::int32_t> cell(3, 5);
    cell.insert(cell.end(), 70, 7);
    cell.push_back(5);
    std::vector<float> x(3 * cell.size());
    for (std::size_t j = 0; j < x.size(); ++j) x[j] = float(j % 11) - float(j % 3);
    const SampleBlocks b = SampleBlocks::build(x.data(), cell.data(), cell.size());
    ASSERT_EQ(b.count(), 4u);
    EXPECT_EQ(b.first, (std::vector<std::uint32_t>{0, 3, 3 + 64, 73, 74}));
    EXPECT_EQ(b.slot, (std::vector<std::uint32_t>{0, 8, 72, 80, 88}));
    for (std::size_t k = 0; k < b.count(); ++k)
        for (int t = 0; t < b.lanesOf(k); ++t) {
            const std::size_t j = std::min<std::size_t>(b.first[k] + std::size_t(t), b.first[k + 1] - 1);
            EXPECT_EQ(b.px[b.slot[k] + std::size_t(t)], x[3 * j]);
            EXPECT_EQ(b.pz[b.slot[k] + std::size_t(t)], x[3 * j + 2]);
            for (int a = 0; a < 3; ++a) {
                EXPECT_LE(b.lo[3 * k + std::size_t(a)], x[3 * j + std::size_t(a)]);
                EXPECT_GE(b.hi[3 * k + std::size_t(a)], x[3 * j + std::size_t(a)]);
            }
        }
}

// The block index lists exactly the blocks whose bounds meet a box (the brute force over every
// block), for small, large, empty and non-finite boxes, with a far outlier block in the grid.
TEST(SampleBlocks, TheIndexFindsEveryBlockABoxMeets)
{
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    std::vector<float> x;
    std::vector<std::int32_t> cell;
    for (int c = 0; c < 400; ++c) { // cells of 10 samples around random centres, one far away
        const float cx = c == 7 ? 900.0f : u(rng), cy = u(rng), cz = u(rng);
        for (int s = 0; s < 10; ++s) {
            x.insert(x.end(), {cx + 0.05f * u(rng), cy + 0.05f * u(rng), cz + 0.05f * u(rng)});
            cell.push_back(c);
        }
    }
    const SampleBlocks b = SampleBlocks::build(x.data(), cell.data(), cell.size());
    const BlockIndex index(b);
    std::vector<std::uint32_t> found;
    int met = 0;
    for (int q = 0; q < 300; ++q) {
        const float half = q % 3 == 0 ? 0.01f : q % 3 == 1 ? 0.2f : 3.0f;
        float lo[3], hi[3];
        for (int a = 0; a < 3; ++a) {
            const float c = u(rng);
            lo[a] = c - half;
            hi[a] = c + half;
        }
        if (q == 5) lo[0] = hi[0] + 1.0f;      // empty
        if (q == 6) hi[1] = INFINITY;          // not finite: meets none
        if (q == 8) lo[2] = NAN;
        if (q == 9) hi[0] = 901.0f;            // reaches the far block
        index.blocksMeeting(b, lo, hi, nullptr, found);
        std::sort(found.begin(), found.end());
        std::vector<std::uint32_t> expected;
        const bool usable = q != 6 && q != 8;
        for (std::uint32_t k = 0; usable && k < b.count(); ++k) {
            const float* bl = &b.lo[3 * k];
            const float* bh = &b.hi[3 * k];
            if (!(bh[0] < lo[0] || bl[0] > hi[0] || bh[1] < lo[1] || bl[1] > hi[1] || bh[2] < lo[2] || bl[2] > hi[2]))
                expected.push_back(k);
        }
        EXPECT_EQ(found, expected) << "query " << q;
        met += !expected.empty();
    }
    EXPECT_GT(met, 150);
}

// Blocks of very different sizes (most small, a few spanning many index cells): every block a box
// meets is listed exactly once, however many of the box's cells it overlaps.
TEST(SampleBlocks, TheIndexListsEachMetBlockOnceWhateverItsSize)
{
    std::mt19937 rng(11);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    const SampleBlocks b = randomCellBlocks(rng, 600, 12, [](int c) { return c % 50 == 0 ? 0.8f : c % 7 == 0 ? 0.2f : 0.03f; });
    const BlockIndex index(b);
    std::vector<std::uint32_t> found;
    std::size_t listed = 0;
    for (int q = 0; q < 400; ++q) {
        const float half = q % 4 == 0 ? 0.005f : q % 4 == 1 ? 0.05f : q % 4 == 2 ? 0.3f : 1.5f;
        float lo[3], hi[3];
        for (int a = 0; a < 3; ++a) {
            const float c = 1.2f * u(rng);
            lo[a] = c - half * (0.5f + 0.5f * (u(rng) + 1.0f));
            hi[a] = c + half;
        }
        index.blocksMeeting(b, lo, hi, nullptr, found);
        std::vector<std::uint32_t> sorted = found;
        std::sort(sorted.begin(), sorted.end());
        EXPECT_EQ(std::adjacent_find(sorted.begin(), sorted.end()), sorted.end()) << "query " << q << " lists a block twice";
        std::vector<std::uint32_t> expected;
        for (std::uint32_t k = 0; k < b.count(); ++k) {
            const float* bl = &b.lo[3 * k];
            const float* bh = &b.hi[3 * k];
            if (!(bh[0] < lo[0] || bl[0] > hi[0] || bh[1] < lo[1] || bl[1] > hi[1] || bh[2] < lo[2] || bl[2] > hi[2]))
                expected.push_back(k);
        }
        EXPECT_EQ(sorted, expected) << "query " << q;
        listed += expected.size();
    }
    EXPECT_GT(listed, 4000u);
}

// A limit below the pairs stops the build and leaves the coverage empty; at the count it is the
// unlimited coverage, and a rebuild that keeps no lists obeys the limit again.
TEST(SampleBlocks, TheCoverageStopsAtItsPairLimit)
{
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    const SampleBlocks b = randomCellBlocks(rng, 300, 8, [](int) { return 0.04f; });
    const std::size_t g = 200;
    std::vector<float> lo(3 * g), hi(3 * g);
    for (std::size_t k = 0; k < g; ++k)
        for (int a = 0; a < 3; ++a) {
            const float c = u(rng), half = k % 10 == 0 ? 3.0f : 0.2f; // every tenth a giant: it meets every block
            lo[3 * k + std::size_t(a)] = c - half;
            hi[3 * k + std::size_t(a)] = c + half;
        }
    BlockCoverage all(b);
    ASSERT_TRUE(all.build(lo.data(), hi.data(), nullptr, g, true));
    const std::uint64_t pairs = all.pairCount();
    ASSERT_GT(pairs, 20u * b.count()); // the giants alone meet every block

    BlockCoverage limited(b);
    EXPECT_FALSE(limited.build(lo.data(), hi.data(), nullptr, g, true, nullptr, pairs - 1));
    EXPECT_EQ(limited.pairCount(), 0u);
    EXPECT_TRUE(limited.blockOffsets().empty());
    EXPECT_FALSE(limited.build(lo.data(), hi.data(), nullptr, g, false, nullptr, 0));
    ASSERT_TRUE(limited.build(lo.data(), hi.data(), nullptr, g, true, nullptr, pairs));
    EXPECT_EQ(limited.blockItems(), all.blockItems());
    EXPECT_EQ(limited.blockOffsets(), all.blockOffsets());
    EXPECT_EQ(limited.blockEntryOf(), all.blockEntryOf());

    // Keeping every list but the first giant's, which grows: the kept lists count toward the limit.
    std::vector<std::uint8_t> keep(g, 1);
    keep[0] = 0;
    for (int a = 0; a < 3; ++a) hi[std::size_t(a)] += 1.0f;
    EXPECT_TRUE(limited.build(lo.data(), hi.data(), nullptr, g, true, keep.data(), pairs));
    EXPECT_EQ(limited.pairCount(), pairs); // it met every block already
    hi[0] = lo[0] - 1.0f;                  // now it meets none: the same limit holds the rest
    EXPECT_TRUE(limited.build(lo.data(), hi.data(), nullptr, g, true, keep.data(), pairs - 1));
    EXPECT_EQ(limited.pairCount(), pairs - b.count());
    EXPECT_FALSE(limited.build(lo.data(), hi.data(), nullptr, g, true, nullptr, pairs - b.count() - 1));
}

// A budget below what the process holds leaves no room for any pair: the solver refuses its coverage
// with an InputError naming the stage (the static one first when there are static Gaussians)
// before allocating it; without a budget the same run goes through.
TEST(CpuSolver, ACoveragePastTheMemoryBudgetIsRefused)
{
    Problem p = makeProblem(0, 3, 41u);
    GaussianCloud cloud = p.start;
    StageTwoOptions o = p.options;
    o.iterations = 2;
    o.maxMemoryBytes = 1;
    ASSERT_GT(residentMemoryBytes(), 1u) << "no resident memory figure here";
    const auto message = [&](const std::vector<std::uint8_t>& moving) {
        try {
            runStageTwo(cloud, p.samples, moving, p.cells, o);
        } catch (const InputError& e) {
            return std::string(e.what());
        }
        return std::string("no error");
    };
    const std::string stays = message(p.moving); // every third Gaussian static
    EXPECT_NE(stays.find("Stage II (the Gaussians that stay): the Gaussians reach more than"), std::string::npos) << stays;
    EXPECT_NE(stays.find("--max-memory"), std::string::npos) << stays;
    EXPECT_NE(stays.find("lower --cells"), std::string::npos) << stays; // deform's advice unless told otherwise
    o.memoryAdvice = "Lower --samples-per-voxel."; // from-vdb's flags
    const std::string moving = message(std::vector<std::uint8_t>(cloud.size(), 1));
    EXPECT_EQ(moving.find("Stage II: the Gaussians reach more than"), 0u) << moving;
    EXPECT_NE(moving.find("). Lower --samples-per-voxel."), std::string::npos) << moving;
    EXPECT_EQ(moving.find("--cells"), std::string::npos) << moving;
    EXPECT_EQ(cloud.means, p.start.means); // refused before any step
    o.maxMemoryBytes = 0;
    EXPECT_EQ(message(p.moving), "no error");
}

TEST(SampleBlocks, BoxMeetsSlabsIsASuperset)
{
    // Random slabs and boxes: whenever a random point of the box lies in all slabs, the box must meet them.
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    int inside = 0;
    for (int trial = 0; trial < 2000; ++trial) {
        CoverageSlabs s;
        const Mat3d r = quatToMatrix(Quatd{u(rng), u(rng), u(rng), u(rng)});
        for (int a = 0; a < 3; ++a) {
            s.centre[a] = u(rng);
            s.half[a] = 0.1f + 0.5f * std::fabs(u(rng));
            for (int k = 0; k < 3; ++k) s.axis[a][k] = float(r.m[k][a]);
        }
        float lo[3], hi[3];
        for (int a = 0; a < 3; ++a) {
            lo[a] = u(rng);
            hi[a] = lo[a] + 0.3f * std::fabs(u(rng));
        }
        const bool meets = boxMeetsSlabs(lo, hi, s);
        for (int i = 0; i < 50; ++i) {
            const float p[3] = {lo[0] + (hi[0] - lo[0]) * std::fabs(u(rng)), lo[1] + (hi[1] - lo[1]) * std::fabs(u(rng)),
                                lo[2] + (hi[2] - lo[2]) * std::fabs(u(rng))};
            if (s.contains(p)) {
                ++inside;
                ASSERT_TRUE(meets) << "trial " << trial;
            }
        }
    }
    EXPECT_GT(inside, 100);
}

TEST(BlockLoops, ChunkTestsNeverSkipACountingLane)
{
    // Random Gaussians (round to flat, near the origin and far from it, where p - m rounds most)
    // against a cell of n^3 samples near them: the block weights must count exactly the lanes
    // where PreparedGaussian::weight() counts, with the same bits, and keep those chunks.
    std::mt19937 rng(11);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    const float cutoff = 1.0f / 255.0f;
    std::uint64_t counted = 0, skipped = 0;
    for (int trial = 0; trial < 600; ++trial) {
        const double offset = trial % 3 == 0 ? 700.0 : 0.0;
        const Vec3d mean(offset + u(rng), offset + u(rng), offset + u(rng));
        const Vec3d scale(0.2 * std::exp(2.0 * u(rng)), 0.2 * std::exp(2.0 * u(rng)),
                          trial % 4 == 0 ? 1e-7 : 0.2 * std::exp(2.0 * u(rng)));
        const Quatd q{u(rng), u(rng), u(rng), u(rng)};
        const PreparedGaussian g = PreparedGaussian::from(
            prepareGaussian(mean, filteredCovariance(q, scale, Mat3d{}), 0.05 + 0.95 * std::fabs(double(u(rng))), double(cutoff)));
        const int n = 2 + trial % 3;
        const float edge = 0.05f + 0.5f * std::fabs(u(rng));
        const float corner[3] = {float(mean.x) + 1.5f * u(rng), float(mean.y) + 1.5f * u(rng), float(mean.z) + 1.5f * u(rng)};
        std::vector<float> x;
        for (int a = 0; a < n; ++a)
            for (int b = 0; b < n; ++b)
                for (int c = 0; c < n; ++c)
                    x.insert(x.end(), {corner[0] + edge * float(a) / float(n), corner[1] + edge * float(b) / float(n),
                                       corner[2] + edge * float(c) / float(n)});
        const std::vector<std::int32_t> cell(x.size() / 3, 0);
        const SampleBlocks blocks = SampleBlocks::build(x.data(), cell.data(), cell.size());
        ASSERT_EQ(blocks.count(), 1u);
        const BlockPoints pts{blocks.px.data(), blocks.py.data(), blocks.pz.data(), blocks.lanesOf(0), blocks.samplesOf(0),
                              blocks.chunksOf(0)};
        // One Gaussian with h = 1 from zero: o and each f row hold its weights.
        const std::vector<float> h(3, 1.0f);
        alignas(32) float f[3 * kMaxBlockSamples] = {}, o[kMaxBlockSamples] = {}, f2[3 * kMaxBlockSamples] = {},
                          o2[kMaxBlockSamples] = {}, kept[kMaxBlockSamples / kSimdLanes * kKeptChunkFloats];
        const ChunkBound cb = ChunkBound::of(g);
        const std::uint32_t item = 0;
        const BlockGaussians gs{&item, 1, &g, &cb, h.data(), 0};
        const std::uint64_t pairs = blockFeatures(gs, pts, cutoff, 3, f, o);
        std::uint8_t chunks = 0;
        std::uint32_t keptAt = 7;
        ASSERT_EQ(blockForward(gs, pts, cutoff, 3, f2, o2, &chunks, kept, &keptAt), pairs) << "trial " << trial;
        EXPECT_EQ(keptAt, 0u);
        int chunk = 0, keptChunks = __builtin_popcount(chunks);
        std::uint64_t mask = 0;
        for (int t0 = 0; t0 < pts.lanes; t0 += kSimdLanes) {
            if (((chunks >> (t0 / kSimdLanes)) & 1u) == 0) continue;
            for (int l = 0; l < kSimdLanes; ++l) {
                EXPECT_EQ(kept[chunk * kKeptChunkFloats + l], o[t0 + l]);
                if (t0 + l < pts.samples && o[t0 + l] > 0.0f) mask |= std::uint64_t(1) << (t0 + l);
            }
            ++chunk;
        }
        EXPECT_EQ(std::uint64_t(__builtin_popcountll(mask)), pairs);
        EXPECT_EQ(chunk, keptChunks);
        for (int t = 0; t < pts.samples; ++t) {
            const Vec3f d(pts.px[t] - g.mean.x, pts.py[t] - g.mean.y, pts.pz[t] - g.mean.z);
            const float ref = g.weight(d, cutoff);
            const bool on = (mask >> t) & 1u;
            ASSERT_EQ(on, ref > 0.0f) << "trial " << trial << " lane " << t;
            EXPECT_EQ(o[t], ref);
            EXPECT_EQ(o2[t], ref);
            EXPECT_EQ(f[2 * pts.lanes + t], ref);
            counted += on ? 1 : 0;
            skipped += on ? 0 : 1;
        }
    }
    EXPECT_GT(counted, 1000u);
    EXPECT_GT(skipped, 1000u);
}
