#include <gtest/gtest.h>

#include <cstdint>
#include <numeric>

#include "core/Memory.h"

using namespace splatwarp;

TEST(BigVector, LargeBuffersSitOnHugePageBoundaries)
{
    BigVector<float> v(std::size_t(3) << 20, 1.5f); // 12 MiB
    EXPECT_EQ(reinterpret_cast<std::uintptr_t>(v.data()) % (std::uintptr_t(2) << 20), 0u);
    for (const float x : v) ASSERT_EQ(x, 1.5f);
}

TEST(BigVector, GrowingKeepsTheContents)
{
    BigVector<std::uint32_t> v(1000);
    std::iota(v.begin(), v.end(), 0u);
    v.resize(std::size_t(4) << 20); // small -> large: moves to the huge-page path
    for (std::uint32_t i = 0; i < 1000; ++i) ASSERT_EQ(v[i], i);
    v.assign(10, 7u);
    EXPECT_EQ(v.size(), 10u);
    for (const std::uint32_t x : v) EXPECT_EQ(x, 7u);
    v.resize(20, 9u); // a value is still written
    EXPECT_EQ(v[19], 9u);
}
