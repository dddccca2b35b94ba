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

Device warpPointsOn(const DeformationGraph& graph, const NodeTransforms& transforms, const float* points,
                    std::size_t count, float* warped, float* rotations, const WarpOptions& o)
{
    const WarpPointsFunction cuda = pointsSlot.get();
    Device used = Device::Cpu;
    runOnDevice(
        o.device, "point warping", cuda != nullptr,
        [&] { return (cuda(graph, transforms, points, count, warped, rotations, o.threaded), 0); },
        [&] { return (warpPoints(graph, transforms, points, count, warped, rotations, o.threaded), 0); }, &used);
    return used;
}

Device warpSamplesOn(SampleSet& samples, const Deformation& d, const WarpOptions& o)
{
    const WarpSamplesFunction cuda = samplesSlot.get();
    Device used = Device::Cpu;
    runOnDevice(
        o.device, "sample warping", cuda != nullptr, [&] { return (cuda(samples, d.graph, d.transforms, o.threaded), 0); },
        [&] { return (warpSamples(samples, d.graph, d.transforms, o.threaded), 0); }, &used);
    return used;
}

} // namespace splatwarp
