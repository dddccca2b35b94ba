#pragma once
/// @file CudaTestSupport.h
/// @brief Skip a GPU test cleanly, with a message, where no usable CUDA device is present; the
///        CUDA backends registered for one test only; the tolerances seen, for the device check.
#include <gtest/gtest.h>

#include <cstdio>
#include <string>

#include "kernels/CudaBackends.h"

#define SPLATWARP_REQUIRE_GPU()                                                                         \
    if (!::splatwarp::cuda::cudaDeviceAvailable())                                                      \
    GTEST_SKIP() << "no usable CUDA GPU (" << ::splatwarp::cuda::cudaDeviceProblem()                    \
                 << "): GPU parity test compiled but not run"

namespace splatwarp::test {

/// @brief The CUDA backends registered for one scope (a test, or a part of one), every slot
///        cleared at its end, even when an assertion returns early: no test sees what another
///        left registered, whatever the order (--gtest_shuffle).
struct CudaBackendsScope {
    CudaBackendsScope() { cuda::registerBackends(); }
    ~CudaBackendsScope() { cuda::unregisterBackends(); }
    CudaBackendsScope(const CudaBackendsScope&) = delete;
    CudaBackendsScope& operator=(const CudaBackendsScope&) = delete;
};

/// @brief Record a measured error against its allowed value: a "[tolerance] name seen allowed"
///        line (scripts/device-benchmarks.sh collects them into its JSON) and a test property.
///        The caller still asserts seen <= allowed.
inline void reportTolerance(const std::string& name, double seen, double allowed)
{
    std::printf("[tolerance] %s seen %.6g allowed %.6g\n", name.c_str(), seen, allowed);
    ::testing::Test::RecordProperty(name, std::to_string(seen));
}

} // namespace splatwarp::test
