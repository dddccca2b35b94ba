#pragma once
/// @file FakeCuda.h
/// @brief A fake CUDA probe and Stage II registered for one test in a CPU-only process, the
///        CPU-only state restored at its end (tests of the device dispatch and its fallbacks).
#include "core/Device.h"
#include "stage2/StageTwoDevice.h"

namespace splatwarp::test {

struct FakeCuda {
    FakeCuda(bool (*probe)(), StageTwoFunction stageTwo)
    {
        registerCudaProbe(probe);
        registerStageTwoCuda(stageTwo);
    }
    ~FakeCuda()
    {
        registerCudaProbe(nullptr);
        registerStageTwoCuda(nullptr);
    }
    FakeCuda(const FakeCuda&) = delete;
    FakeCuda& operator=(const FakeCuda&) = delete;
};

inline bool noGpu() { return false; }
inline bool gpu() { return true; }

} // namespace splatwarp::test
