#include "field/FeatureDevice.h"

#include <atomic>
#include <vector>

namespace splatwarp {
namespace {

std::atomic<SampleTargetsFunction>& targetsSlot()
{
    static std::atomic<SampleTargetsFunction> f{nullptr};
    return f;
}

std::atomic<FeaturesFunction>& featuresSlot()
{
    static std::atomic<FeaturesFunction> f{nullptr};
    return f;
}

} // namespace

void registerSampleTargetsCuda(SampleTargetsFunction cuda) { targetsSlot().store(cuda); }

SampleTargetsFunction sampleTargetsCuda() { return targetsSlot().load(); }

void registerFeaturesCuda(FeaturesFunction cuda) { featuresSlot().store(cuda); }

Device evaluateFeaturesOn(const GaussianCloud& cloud, const float* points, std::size_t m, const FeatureOptions& options,
                          float* features, float* opacity, FeatureStats* stats)
{
    const FeaturesFunction cuda = featuresSlot().load();
    Device used = Device::Cpu;
    const FeatureStats s = runOnDevice(
        options.device, "features", cuda != nullptr,
        [&] {
            checkFeatureOptions(options);
            const std::vector<PreparedGaussian> g = prepareCloud(cloud, options.filterVariance, options.cutoff, options.threaded);
            FeaturePointsProblem p;
            p.cloud = preparedView(g, cloud, options.cutoff);
            p.points = points;
            p.count = m;
            FeatureStats s;
            cuda(p, features, opacity, &s);
            return s;
        },
        [&] {
            FeatureStats s;
            evaluateFeatures(cloud, points, m, options, features, opacity, &s);
            return s;
        },
        &used);
    if (stats) {
        stats->pairsTested += s.pairsTested;
        stats->pairsContributing += s.pairsContributing;
        stats->binEntries = s.binEntries;
        stats->binCellSize = s.binCellSize;
    }
    return used;
}

} // namespace splatwarp
