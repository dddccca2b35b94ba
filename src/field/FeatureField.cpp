#include "field/FeatureField.h"

#include <tbb/enumerable_thread_specific.h>

#include <algorithm>

#include "core/Error.h"
#include "core/ParallelFor.h"
#include "field/CellTargetMath.h"

namespace splatwarp {
namespace {

struct Counters {
    std::uint64_t tested = 0, contributing = 0;
};

} // namespace

std::vector<PreparedGaussian> prepareCloud(const GaussianCloud& cloud, double filterVariance, double cutoff,
                                           bool threaded)
{
    cloud.checkConsistent();
    std::vector<PreparedGaussian> out(cloud.size());
    parallelFor(cloud.size(), 1024, threaded,
                [&](std::size_t i) { out[i] = prepareGaussian(cloud, i, filterVariance, cutoff); });
    return out;
}

void binPreparedGaussians(const std::vector<PreparedGaussian>& gaussians, float cellSize, bool threaded,
                          GaussianBins& bins)
{
    const std::size_t n = gaussians.size();
    std::vector<float> lo(3 * n), hi(3 * n);
    for (std::size_t i = 0; i < n; ++i) preparedBox(gaussians[i], &lo[3 * i], &hi[3 * i]);
    if (cellSize <= 0.0f) cellSize = GaussianBins::suggestCellSize(lo.data(), hi.data(), n);
    bins.build(lo.data(), hi.data(), n, cellSize, threaded);
}

void evaluatePreparedFeatures(const std::vector<PreparedGaussian>& gaussians, const float* sh, int shStride,
                              const GaussianBins& bins, const float* points, std::size_t m, float cutoff,
                              bool threaded, float* features, float* opacity, FeatureStats* stats)
{
    tbb::enumerable_thread_specific<Counters> counters;
    parallelForRange(m, 256, threaded, [&](std::size_t begin, std::size_t end) {
        Counters& c = counters.local();
        for (std::size_t p = begin; p != end; ++p) {
            const Vec3f x(points[3 * p], points[3 * p + 1], points[3 * p + 2]);
            float* f = features ? features + p * std::size_t(shStride) : nullptr;
            float o = 0.0f;
            const std::uint32_t* cand = nullptr;
            const std::size_t count = bins.candidates(x, &cand);
            c.tested += count;
            c.contributing += accumulateFeatures(x, cand, count, gaussians.data(), sh, shStride, cutoff, f, o);
            if (opacity) opacity[p] = o;
        }
    });
    if (stats) {
        for (const Counters& c : counters) {
            stats->pairsTested += c.tested;
            stats->pairsContributing += c.contributing;
        }
        stats->binEntries = bins.entryCount();
        stats->binCellSize = bins.cellSize();
    }
}

void checkFeatureOptions(const FeatureOptions& options)
{
    if (!(options.cutoff > 0.0f)) throw InputError(msg("feature cutoff ", options.cutoff, " must be positive"));
    if (options.filterVariance < 0.0f)
        throw InputError(msg("low-pass filter variance ", options.filterVariance, " must not be negative"));
}

void evaluateFeatures(const GaussianCloud& cloud, const float* points, std::size_t m, const FeatureOptions& options,
                      float* features, float* opacity, FeatureStats* stats)
{
    checkFeatureOptions(options);
    const std::vector<PreparedGaussian> prepared =
        prepareCloud(cloud, options.filterVariance, options.cutoff, options.threaded);
    GaussianBins bins;
    binPreparedGaussians(prepared, 0.0f, options.threaded, bins);
    evaluatePreparedFeatures(prepared, cloud.sh.data(), cloud.shStride(), bins, points, m, options.cutoff,
                             options.threaded, features, opacity, stats);
}

} // namespace splatwarp

namespace splatwarp {

void evaluateSampleTargets(const GaussianCloud& cloud, SampleSet& samples, const FeatureOptions& options)
{
    if (samples.shDegree != cloud.shDegree)
        throw InputError(msg("sample set SH degree ", samples.shDegree, " differs from the model's ", cloud.shDegree));
    const std::size_t m = samples.restPositions.size() / 3;
    samples.targetF.resize(m * std::size_t(samples.featureStride()));
    samples.targetO.resize(m);
    evaluateFeatures(cloud, samples.restPositions.data(), m, options, samples.targetF.data(), samples.targetO.data());
}

} // namespace splatwarp
