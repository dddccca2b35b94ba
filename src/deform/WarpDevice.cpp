#include "deform/WarpDevice.h"

namespace splatwarp {
namespace {

CudaSlot<WarpPointsFunction> pointsSlot;
CudaSlot<WarpSamplesFunction> samplesSlot;

} // namespace

void registerWarpCuda(WarpPointsFunction points, WarpSamplesFunction samples)
{
    pointsSlot.set(points);
    samplesSlot.set(samples);
}

const char* warpPointsOn(Device device, const DeformationGraph& graph, const NodeTransforms& transforms,
                         const float* points, std::size_t count, float* warped, float* rotations, bool threaded)
{
    const WarpPointsFunction cuda = pointsSlot.get();
    Device used = Device::Cpu;
    runOnDevice(
        device, "point warping", cuda != nullptr,
        [&] { return (cuda(graph, transforms, points, count, warped, rotations, threaded), 0); },
        [&] { return (warpPoints(graph, transforms, points, count, warped, rotations, threaded), 0); }, &used);
    return deviceName(used);
}

const char* warpSamplesOn(Device device, SampleSet& samples, const Deformation& d, bool threaded)
{
    const WarpSamplesFunction cuda = samplesSlot.get();
    Device used = Device::Cpu;
    runOnDevice(
        device, "sample warping", cuda != nullptr,
        [&] { return (cuda(samples, d.graph, d.transforms, threaded), 0); },
        [&] { return (warpSamples(samples, d.graph, d.transforms, threaded), 0); }, &used);
    return deviceName(used);
}

} // namespace splatwarp
