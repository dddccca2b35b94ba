// evaluateFeaturesOn() in a build without registered CUDA: Cpu and Auto run the CPU path (the
// same numbers and counters as evaluateFeatures()), Cuda is refused with InputError (without a
// GPU when resolved, with a GPU but no CUDA feature evaluation when run).
#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "field/FeatureDevice.h"
#include "field/FieldTestModels.h"

using namespace splatwarp;

namespace {

bool gpu() { return true; }

/// A GPU probe without a CUDA feature evaluation, for one test.
struct ProbeOnly {
    ProbeOnly() { registerCudaProbe(&gpu); }
    ~ProbeOnly() { registerCudaProbe(nullptr); }
};

} // namespace

TEST(FeatureDevice, CpuAndAutoRunTheCpuPathAndCudaIsRefused)
{
    const GaussianCloud cloud = test::randomCloud(200, 1, 9u, 1.0f);
    std::mt19937 rng(2);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    const std::size_t m = 2000;
    std::vector<float> points(3 * m);
    for (float& v : points) v = u(rng);
    const std::size_t stride = std::size_t(cloud.shStride());
    FeatureOptions o;
    std::vector<float> f0(m * stride), o0(m), f1(m * stride), o1(m);
    FeatureStats s0, s1;
    evaluateFeatures(cloud, points.data(), m, o, f0.data(), o0.data(), &s0);
    for (const Device d : {Device::Cpu, Device::Auto}) {
        o.device = resolveDevice(d);
        s1 = {};
        EXPECT_EQ(evaluateFeaturesOn(cloud, points.data(), m, o, f1.data(), o1.data(), &s1), Device::Cpu);
        EXPECT_EQ(f1, f0);
        EXPECT_EQ(o1, o0);
        EXPECT_EQ(s1.pairsContributing, s0.pairsContributing);
        EXPECT_EQ(s1.pairsTested, s0.pairsTested);
    }
    EXPECT_GT(s0.pairsContributing, 0u);
    EXPECT_THROW(resolveDevice(Device::Cuda), InputError);
    const ProbeOnly probe;
    o.device = resolveDevice(Device::Cuda);
    EXPECT_THROW(evaluateFeaturesOn(cloud, points.data(), m, o, f1.data(), o1.data()), InputError);
    o.device = resolveDevice(Device::Auto);
    EXPECT_EQ(evaluateFeaturesOn(cloud, points.data(), m, o, f1.data(), o1.data()), Device::Cpu);
    EXPECT_EQ(o1, o0);
}
