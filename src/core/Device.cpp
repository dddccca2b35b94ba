#include "core/Device.h"

namespace splatwarp {
namespace {

CudaSlot<bool (*)()> probeSlot;

} // namespace

Device parseDevice(const std::string& name)
{
    if (name == "auto") return Device::Auto;
    if (name == "cpu") return Device::Cpu;
    if (name == "cuda") return Device::Cuda;
    throw InputError(msg("unknown device '", name, "': expected auto, cpu or cuda"));
}

const char* deviceName(Device device)
{
    switch (device) {
    case Device::Auto: return "auto";
    case Device::Cpu: return "cpu";
    case Device::Cuda: return "cuda";
    }
    return "?";
}

bool cudaCompiledIn() { return probeSlot.get() != nullptr; }

bool cudaPresent()
{
    bool (*probe)() = probeSlot.get();
    return probe && probe();
}

ResolvedDevice resolveDevice(Device requested)
{
    switch (requested) {
    case Device::Cpu: return {};
    case Device::Auto: return {requested, cudaPresent() ? Device::Cuda : Device::Cpu};
    case Device::Cuda:
        if (!cudaCompiledIn())
            throw InputError("--device cuda: this build has no CUDA support (rebuild with nvcc available, "
                             "or use --device cpu)");
        if (!cudaPresent()) throw InputError("--device cuda: no usable CUDA GPU found (use --device cpu or auto)");
        return {requested, Device::Cuda};
    }
    return {};
}

void fallBackToCpu(const ResolvedDevice& device, const char* what, const DeviceLimitError& e)
{
    if (!device.cpuFallback()) {
        const std::string text = msg(e.what(), " (--device cuda; --device auto would run ", what, " on the CPU)");
        if (dynamic_cast<const DeviceMemoryError*>(&e)) throw DeviceMemoryError(text);
        throw DeviceLimitError(text);
    }
    progress(msg(what, ": ", e.what(), "; running on the CPU instead"));
}

void registerCudaProbe(bool (*probe)()) { probeSlot.set(probe); }

} // namespace splatwarp
