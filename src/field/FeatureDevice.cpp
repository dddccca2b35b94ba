#include "field/FeatureDevice.h"

#include <vector>

namespace splatwarp {
namespace {

CudaSlot<SampleTargetsFunction> targetsSlot;
CudaSlot<FeaturesFunction> featuresSlot;

} // namespace

void registerSampleTargetsCuda(SampleTargetsFunction cuda) { targetsSlot.set(cuda); }

SampleTargetsFunction sampleTargetsCuda() { return targetsSlot.get(); }

void registerFeaturesCuda(FeaturesFunction cuda) { featuresSlot.set(cuda); }

Device evaluateFeaturesOn(const GaussianCloud& cloud, const float* points, std::size_t m, const FeatureOptions& options,
                          float* features, float* opacity, FeatureStats* stats)
{
    const FeaturesFunction cuda = featuresSlot.get();
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
