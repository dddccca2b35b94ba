#include "stage2/BlockFeatures.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "core/Error.h"
#include "core/MortonOrder.h"
#include "core/ParallelFor.h"
#include "field/FeatureDevice.h"
#include "stage2/BlockLoops.h"
#include "stage2/SampleBlocks.h"

namespace splatwarp {
namespace {

/// Relative allowance for the float rounding of the weight test against the exact slab bounds.
constexpr double kSlabRounding = 1e-5;

/// Slabs along the Gaussian's own axes holding its prepared cutoff ellipsoid: with an isotropic
/// filter f, R diag(v) R^T + f I has the axes of R and variances v + f.
CoverageSlabs preparedSlabs(const GaussianCloud& cloud, std::size_t i, const PreparedGaussian& g, double filterVariance)
{
    CoverageSlabs s;
    if (!(g.radius2 > 0)) return s; // never contributes: half < 0 holds nothing
    const Quatd q{cloud.rotations[4 * i], cloud.rotations[4 * i + 1], cloud.rotations[4 * i + 2], cloud.rotations[4 * i + 3]};
    const Mat3d r = quatToMatrix(q);
    const Vec3d v = clampedVariances(Vec3d(cloud.scale(i)));
    const double radius = std::sqrt(double(g.radius2));
    for (int a = 0; a < 3; ++a) {
        s.centre[a] = g.mean[a];
        for (int k = 0; k < 3; ++k) s.axis[a][k] = float(r.m[k][a]);
        const double half = radius * std::sqrt(v[a] + filterVariance);
        s.half[a] = float(half * (1 + kSlabRounding) + kSlabRounding * (std::fabs(g.mean.x) + std::fabs(g.mean.y) + std::fabs(g.mean.z)));
    }
    return s;
}

/// Points in Morton order with their block cell: the coarsest level of the Morton lattice whose
/// cells hold at least kPointsPerCell points on average (SampleBlocks cuts longer runs).
struct MortonBlocks {
    static constexpr std::size_t kPointsPerCell = 32;
    std::vector<std::uint32_t> order; ///< sorted position -> point
    std::vector<float> points;        ///< [m,3] in sorted order
    std::vector<std::int32_t> cell;   ///< [m] in sorted order

    MortonBlocks(const float* x, std::size_t m, bool threaded)
    {
        MortonOrder sorted(x, m, threaded);
        const std::vector<std::uint64_t>& key = sorted.key;
        order = std::move(sorted.order);
        int shift = 0; // bits dropped: cells of 2^(shift/3) finest cells a side
        for (; shift < 30; shift += 3)
            if (m >= kPointsPerCell * distinct(key, shift)) break;
        points.resize(3 * m);
        cell.resize(m);
        std::int32_t c = -1;
        for (std::size_t j = 0; j < m; ++j) {
            const std::uint32_t i = order[j];
            if (j == 0 || key[i] >> shift != key[order[j - 1]] >> shift) ++c;
            cell[j] = c;
            for (int a = 0; a < 3; ++a) points[3 * j + a] = x[3 * i + a];
        }
    }

private:
    std::size_t distinct(const std::vector<std::uint64_t>& key, int shift) const
    {
        std::size_t n = 0;
        for (std::size_t j = 0; j < order.size(); ++j) n += j == 0 || key[order[j]] >> shift != key[order[j - 1]] >> shift;
        return n;
    }
};

} // namespace

namespace {

/// evaluateBlockFeatures() over blocks already cut; with an order, the blocks' point j is the
/// output's point order[j] (PointBlocks: written in place, no sorted copy to scatter).
FeatureStats evaluateSampleBlocks(const GaussianCloud& cloud, const SampleBlocks& blocks, const FeatureOptions& options,
                                  float* features, float* opacity, const std::uint32_t* order = nullptr)
{
    checkFeatureOptions(options);
    const std::vector<PreparedGaussian> prepared = prepareCloud(cloud, options.filterVariance, options.cutoff, options.threaded);
    const std::size_t n = prepared.size();
    std::vector<float> lo(3 * n), hi(3 * n);
    std::vector<CoverageSlabs> slabs(n);
    std::vector<ChunkBound> bounds(n);
    parallelFor(n, 1024, options.threaded, [&](std::size_t i) {
        bounds[i] = ChunkBound::of(prepared[i]);
        preparedBox(prepared[i], &lo[3 * i], &hi[3 * i]);
        slabs[i] = preparedSlabs(cloud, i, prepared[i], double(options.filterVariance));
    });
    BlockCoverage coverage(blocks);
    const std::uint64_t limit = coveragePairLimit(options.maxListBytes, 0.0, double(kCoveragePairBytes));
    if (!coverage.build(lo.data(), hi.data(), slabs.data(), n, options.threaded, nullptr, limit))
        throw coverageTooLarge("field evaluation", limit, double(kCoveragePairBytes),
                               msg("the ", formatBytes(double(options.maxListBytes)), " that --max-memory leaves for them"));
    const int stride = cloud.shStride();
    std::vector<std::uint64_t> tested(blocks.count()), counted(blocks.count());
    parallelFor(blocks.count(), 4, options.threaded, [&](std::size_t b) {
        const std::size_t s0 = blocks.slot[b], j0 = blocks.first[b];
        const BlockPoints pts{&blocks.px[s0], &blocks.py[s0], &blocks.pz[s0], blocks.lanesOf(b), blocks.samplesOf(b),
                          blocks.chunksOf(b)};
        const std::size_t lanes = std::size_t(pts.lanes);
        alignas(32) float f[kMaxShStride * kMaxBlockSamples] = {}, o[kMaxBlockSamples] = {};
        const std::uint64_t e0 = coverage.blockOffsets()[b];
        const BlockGaussians gs{coverage.blockItems().data() + e0, std::size_t(coverage.blockOffsets()[b + 1] - e0),
                                prepared.data(), bounds.data(), cloud.sh.data(), std::size_t(stride)};
        tested[b] = gs.n * std::uint64_t(pts.samples);
        counted[b] = blockFeatures(gs, pts, options.cutoff, stride, f, o);
        for (std::size_t t = 0; t < std::size_t(pts.samples); ++t) {
            const std::size_t i = order ? std::size_t(order[j0 + t]) : j0 + t;
            if (opacity) opacity[i] = o[t];
            if (features)
                for (std::size_t c = 0; c < std::size_t(stride); ++c) features[i * std::size_t(stride) + c] = f[c * lanes + t];
        }
    });
    FeatureStats stats;
    for (std::size_t b = 0; b < blocks.count(); ++b) {
        stats.pairsTested += tested[b];
        stats.pairsContributing += counted[b];
    }
    stats.binEntries = coverage.pairCount();
    return stats;
}

} // namespace

FeatureStats evaluateBlockFeatures(const GaussianCloud& cloud, const float* points, const std::int32_t* cell, std::size_t m,
                                   const FeatureOptions& options, float* features, float* opacity)
{
    return evaluateSampleBlocks(cloud, SampleBlocks::build(points, cell, m, options.threaded), options, features, opacity);
}

PointBlocks::PointBlocks(const float* points, std::size_t m, bool threaded)
{
    if (m == 0 || m > std::size_t(std::numeric_limits<std::int32_t>::max())) return;
    for (std::size_t j = 0; j < 3 * m; ++j)
        if (!std::isfinite(points[j])) return; // no box holds it: the per-point evaluation decides
    MortonBlocks sorted(points, m, threaded);
    mBlocks = std::make_unique<SampleBlocks>(SampleBlocks::build(sorted.points.data(), sorted.cell.data(), m, threaded));
    mOrder = std::move(sorted.order);
}

PointBlocks::~PointBlocks() = default;

FeatureStats PointBlocks::evaluate(const GaussianCloud& cloud, const FeatureOptions& options, float* features, float* opacity) const
{
    if (!mBlocks) throw Error("PointBlocks::evaluate on points the block engine does not take");
    return evaluateSampleBlocks(cloud, *mBlocks, options, features, opacity, mOrder.data());
}

FeatureStats evaluatePointFeatures(const GaussianCloud& cloud, const float* points, std::size_t m,
                                   const FeatureOptions& options, float* features, float* opacity)
{
    const PointBlocks blocks(points, m, options.threaded);
    if (blocks.usable()) return blocks.evaluate(cloud, options, features, opacity);
    FeatureStats s;
    evaluateFeatures(cloud, points, m, options, features, opacity, &s);
    return s;
}

Device evaluatePointsOn(const GaussianCloud& cloud, const float* points, std::size_t m, const FeatureOptions& options,
                        float* features, float* opacity)
{
    if (options.device.cuda()) return evaluateFeaturesOn(cloud, points, m, options, features, opacity);
    evaluatePointFeatures(cloud, points, m, options, features, opacity);
    return Device::Cpu;
}

} // namespace splatwarp
