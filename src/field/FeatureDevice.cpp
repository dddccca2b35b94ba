#include "field/FeatureDevice.h"

#include <atomic>

namespace splatwarp {
namespace {

std::atomic<SampleTargetsFunction>& targetsSlot()
{
    static std::atomic<SampleTargetsFunction> f{nullptr};
    return f;
}

} // namespace

void registerSampleTargetsCuda(SampleTargetsFunction cuda) { targetsSlot().store(cuda); }

SampleTargetsFunction sampleTargetsCuda() { return targetsSlot().load(); }

} // namespace splatwarp
