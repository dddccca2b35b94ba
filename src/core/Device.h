#pragma once
/// @file Device.h
/// @brief Which device runs the heavy stages (`--device auto|cpu|cuda`). The core library
///        cannot link the CUDA kernels, so the kernels register a probe (and their stage
///        implementations, see stage2/StageTwoDevice.h) at start-up; with nothing registered
///        this is a CPU-only build.
#include <atomic>
#include <string>

#include "core/Error.h"
#include "core/Progress.h"

namespace splatwarp {

/// @brief A requested or resolved device.
enum class Device { Auto, Cpu, Cuda };

/// @brief The GPU ran out of memory. The message names what did not fit and how many bytes,
///        so the caller can report it or fall back to the CPU.
class DeviceMemoryError : public Error {
public:
    using Error::Error;
};

/// @brief Parse "auto", "cpu" or "cuda".
/// @throws InputError naming the bad value and the accepted ones
Device parseDevice(const std::string& name);

/// @brief "auto", "cpu" or "cuda".
const char* deviceName(Device device);

/// @brief Whether the CUDA kernels were registered (a build with CUDA that called
///        cuda::registerBackends()).
bool cudaCompiledIn();

/// @brief Whether a CUDA GPU can be used (compiled in and the registered probe finds one).
bool cudaPresent();

/// @brief Auto -> Cuda when compiled in and a GPU is present, else Cpu; Cpu -> Cpu.
/// @throws InputError for Cuda in a build without CUDA support or without a usable GPU
Device resolveDevice(Device requested);

/// @brief Register the CUDA probe (returns whether a GPU is usable); nullptr unregisters.
///        Called by the kernels' registerBackends() (tests may register fakes).
void registerCudaProbe(bool (*probe)());

/// @brief Where the core library keeps one registered CUDA implementation (a function pointer F;
///        null: none, a CPU-only build). The kernels store it at start-up (cuda::registerBackends,
///        or a test's fake); the dispatcher loads it per call. Constant-initialised, so it can be
///        used from any static initialiser.
template <typename F>
class CudaSlot {
public:
    void set(F f) { mF.store(f); }
    F get() const { return mF.load(); }

private:
    std::atomic<F> mF{nullptr};
};

/// @brief Run a computation on a device: the registered CUDA implementation `cuda` (may be null:
///        no CUDA version compiled in) when `requested` resolves to CUDA, else `cpu`. Under Auto a
///        GPU out-of-memory error falls back to the CPU with a progress line naming `what`; under
///        Cuda it propagates. `used` (optional) receives the device that ran.
/// @throws InputError when Cuda is requested but unavailable (see resolveDevice())
template <typename CudaFn, typename CpuFn>
auto runOnDevice(Device requested, const char* what, bool hasCuda, CudaFn&& cuda, CpuFn&& cpu, Device* used = nullptr)
    -> decltype(cpu())
{
    if (resolveDevice(requested) == Device::Cuda) {
        if (!hasCuda) {
            if (requested == Device::Cuda) throw InputError(msg("--device cuda: this build has no CUDA ", what));
        } else {
            try {
                auto result = cuda();
                if (used) *used = Device::Cuda;
                return result;
            } catch (const DeviceMemoryError& e) {
                if (requested == Device::Cuda)
                    throw DeviceMemoryError(msg(e.what(), " (--device cuda; --device auto would fall back to the CPU)"));
                progress(msg(what, ": ", e.what(), "; running on the CPU instead"));
            }
        }
    }
    if (used) *used = Device::Cpu;
    return cpu();
}

} // namespace splatwarp
