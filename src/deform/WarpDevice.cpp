#include "deform/WarpDevice.h"

#include <atomic>

namespace splatwarp {
namespace {

std::atomic<WarpPointsFunction>& pointsSlot()
{
    static std::atomic<WarpPointsFunction> f{nullptr};
    return f;
}

std::atomic<WarpSamplesFunction>& samplesSlot()
{
    static std::atomic<WarpSamplesFunction> f{nullptr};
    return f;
}

} // namespace

void registerWarpCuda(WarpPointsFunction points, WarpSamplesFunction samples)
{
    pointsSlot().store(points);
    samplesSlot().store(samples);
}

const char* warpPointsOn(Device device, const DeformationGraph& graph, const NodeTransforms& transforms,
                         const float* points, std::size_t count, float* warped, float* rotations, bool threaded)
{
    const WarpPointsFunction cuda = pointsSlot().load();
    Device used = Device::Cpu;
    runOnDevice(
        device, "point warping", cuda != nullptr,
        [&] { return (cuda(graph, transforms, points, count, warped, rotations, threaded), 0); },
        [&] { return (warpPoints(graph, transforms, points, count, warped, rotations, threaded), 0); }, &used);
    return deviceName(used);
}

const char* warpSamplesOn(Device device, SampleSet& samples, const Deformation& d, bool threaded)
{
    const WarpSamplesFunction cuda = samplesSlot().load();
    Device used = Device::Cpu;
    runOnDevice(
        device, "sample warping", cuda != nullptr,
        [&] { return (cuda(samples, d.graph, d.transforms, threaded), 0); },
        [&] { return (warpSamples(samples, d.graph, d.transforms, threaded), 0); }, &used);
    return deviceName(used);
}

} // namespace splatwarp
