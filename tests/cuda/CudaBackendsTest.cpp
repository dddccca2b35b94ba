// The device probe and test registration, without a GPU: which compute capabilities this build's
// architectures run on (an old GPU must be refused by the probe, not fail at the first launch),
// and that a test's CudaBackendsScope leaves nothing registered for the next test.
#include <gtest/gtest.h>

#include "kernels/CudaArch.h"
#include "CudaTestSupport.h"
#include "core/Device.h"
#include "field/FeatureDevice.h"

using namespace splatwarp;

TEST(CudaArch, ArchitecturesAgainstComputeCapability)
{
    using cuda::architecturesRunOn;
    // The default build: Turing SASS, Hopper SASS and PTX.
    EXPECT_TRUE(architecturesRunOn("75-real;90", 7, 5));
    EXPECT_FALSE(architecturesRunOn("75-real;90", 7, 0));  // SASS needs a minor >= 5
    EXPECT_FALSE(architecturesRunOn("75-real;90", 6, 1));  // Pascal: nothing runs
    EXPECT_FALSE(architecturesRunOn("75-real;90", 8, 6));  // Ampere: no SASS, the PTX is newer
    EXPECT_TRUE(architecturesRunOn("75-real;90", 9, 0));
    EXPECT_TRUE(architecturesRunOn("75-real,90", 12, 0)); // Blackwell: the PTX JIT-compiles
    EXPECT_FALSE(architecturesRunOn("90-real", 10, 0));   // SASS only: no newer major
    EXPECT_FALSE(architecturesRunOn("90-virtual", 8, 9));
    EXPECT_TRUE(architecturesRunOn("90-virtual", 10, 0));
    EXPECT_TRUE(architecturesRunOn("80", 8, 6));
    EXPECT_TRUE(architecturesRunOn("90a", 9, 0));
    EXPECT_FALSE(architecturesRunOn("90a", 10, 0));        // architecture-specific: no PTX forward
    EXPECT_TRUE(architecturesRunOn("native", 6, 1));       // unknown entries: the runtime decides
    EXPECT_FALSE(architecturesRunOn("", 9, 0));
}

// The lent machines are Hopper (H100, H200): a build that cannot run there wastes the device run.
TEST(CudaArch, ThisBuildRunsOnHopper)
{
    const std::string archs = cuda::compiledArchitectures();
    ASSERT_FALSE(archs.empty());
    EXPECT_TRUE(cuda::architecturesRunOn(archs, 9, 0)) << "compiled for " << archs;
}

// With a device: the probe's answer is the runtime's (a kernel image loads).
TEST(CudaArch, ProbeAgreesWithTheRuntime)
{
    SPLATWARP_REQUIRE_GPU();
    EXPECT_TRUE(cuda::kernelImageLoads());
}

// Every test that registers uses a scope, so between tests nothing is registered, whatever order
// they run in (run with --gtest_shuffle to check the others).
TEST(CudaBackends, ScopeRegistersForItsTestOnly)
{
    EXPECT_FALSE(cudaCompiledIn()) << "an earlier test left the CUDA backends registered";
    EXPECT_EQ(sampleTargetsCuda(), nullptr);
    {
        const test::CudaBackendsScope backends;
        EXPECT_TRUE(cudaCompiledIn());
        EXPECT_NE(sampleTargetsCuda(), nullptr);
        EXPECT_EQ(resolveDevice(Device::Auto).cuda(), cuda::cudaDeviceAvailable());
    }
    EXPECT_FALSE(cudaCompiledIn());
    EXPECT_EQ(sampleTargetsCuda(), nullptr);
}
