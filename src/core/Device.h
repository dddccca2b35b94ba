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

/// @brief The GPU cannot take this job, though the CPU can: a count past the GPU path's 32-bit
///        indices (its per-sample lists are n^3 times longer than the CPU's per-block ones) or,
///        as DeviceMemoryError, a buffer that does not fit. Under Auto the job runs on the CPU
///        (fallBackToCpu()); under Cuda it is an error (exit 1). Never for bad input.
class DeviceLimitError : public Error {
public:
    using Error::Error;
};

/// @brief The GPU ran out of memory. The message names what did not fit and how many bytes,
///        so the caller can report it or fall back to the CPU.
class DeviceMemoryError : public DeviceLimitError {
public:
    using DeviceLimitError::DeviceLimitError;
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

/// @brief A device resolved once per job (resolveDevice()), carried in the options of every
///        operation: where it runs (Cpu or Cuda, never Auto) and whether an operation that runs
///        out of GPU memory may fall back to the CPU (Auto was asked). Only resolveDevice() makes
///        a Cuda one, after its probe found a GPU; the default is the CPU (no probe).
class ResolvedDevice {
public:
    ResolvedDevice() = default;
    /// Cpu or Cuda.
    Device device() const { return mDevice; }
    /// What was asked: Auto, Cpu or Cuda.
    Device requested() const { return mRequested; }
    bool cuda() const { return mDevice == Device::Cuda; }
    /// Auto was asked: when the GPU cannot take a job (DeviceLimitError) or an operation has no
    /// CUDA version, run it on the CPU.
    bool cpuFallback() const { return mRequested == Device::Auto; }

private:
    friend ResolvedDevice resolveDevice(Device requested);
    ResolvedDevice(Device requested, Device device) : mRequested(requested), mDevice(device) {}
    Device mRequested = Device::Cpu;
    Device mDevice = Device::Cpu;
};

/// @brief Auto -> Cuda when compiled in and a GPU is present, else Cpu; Cpu -> Cpu (the one GPU
///        probe of a job).
/// @throws InputError for Cuda in a build without CUDA support or without a usable GPU
ResolvedDevice resolveDevice(Device requested);

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

/// @brief The GPU could not take `what` on `device` (out of memory or past its index limits):
///        under Auto, a progress line says `what` runs on the CPU instead; under Cuda the error
///        is rethrown, of the same type, with a hint.
/// @throws DeviceMemoryError or DeviceLimitError when `device` may not fall back to the CPU
void fallBackToCpu(const ResolvedDevice& device, const char* what, const DeviceLimitError& error);

/// @brief Run a computation on a resolved device: the registered CUDA implementation `cuda` (may
///        be null: no CUDA version compiled in) when `device` is Cuda, else `cpu`. Under Auto a
///        DeviceLimitError (out of memory, a count past the GPU's indices) or no CUDA version runs `cpu` instead, see fallBackToCpu(); under
///        Cuda it propagates. `used` (optional) receives the device that ran.
/// @throws InputError when Cuda was asked and there is no CUDA version of `what`
template <typename CudaFn, typename CpuFn>
auto runOnDevice(const ResolvedDevice& device, const char* what, bool hasCuda, CudaFn&& cuda, CpuFn&& cpu,
                 Device* used = nullptr) -> decltype(cpu())
{
    if (device.cuda()) {
        if (!hasCuda) {
            if (!device.cpuFallback()) throw InputError(msg("--device cuda: this build has no CUDA ", what));
        } else {
            try {
                auto result = cuda();
                if (used) *used = Device::Cuda;
                return result;
            } catch (const DeviceLimitError& e) {
                fallBackToCpu(device, what, e);
            }
        }
    }
    if (used) *used = Device::Cpu;
    return cpu();
}

} // namespace splatwarp
