#include "stage2/BlockFeatures.h"

#include <cmath>

#include "core/ParallelFor.h"
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

} // namespace

FeatureStats evaluateBlockFeatures(const GaussianCloud& cloud, const float* points, const std::int32_t* cell, std::size_t m,
                                   const FeatureOptions& options, float* features, float* opacity)
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
    const SampleBlocks blocks = SampleBlocks::build(points, cell, m);
    BlockCoverage coverage(blocks);
    coverage.build(lo.data(), hi.data(), slabs.data(), n, options.threaded);
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
            if (opacity) opacity[j0 + t] = o[t];
            if (features)
                for (std::size_t c = 0; c < std::size_t(stride); ++c) features[(j0 + t) * std::size_t(stride) + c] = f[c * lanes + t];
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

} // namespace splatwarp
